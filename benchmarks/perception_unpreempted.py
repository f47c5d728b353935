"""Perception wall clock on a loaded machine, counting only the calls the scheduler did not preempt.

    python benchmarks/perception_unpreempted.py [--other /tmp/main_src] [--rounds 4] [--repeats 25]
                                                [--data ../shared/data/dlo_images]

On a shared machine most ``perceive`` calls are preempted, so their wall clock measures the load. Each call here
records its wall clock, its thread CPU time and the thread's involuntary context switches (``getrusage``,
RUSAGE_THREAD); a call with none ran without being preempted, so its wall clock is what an idle machine would
give, apart from the cache and memory bandwidth the other CPU's processes share. The pipeline runs on one thread
(process CPU time = the calling thread's), so nothing else of the call is missed. Reported per image: the number
of such calls and their median wall clock, for this checkout and (``--other``) another one, in alternating
processes as ``perception_side_by_side.py``. When no call escapes preemption, a rough estimate instead: the
intercept of a straight-line fit of each photo's thread CPU time against the number of preemptions per call (the
CPU time a call would take without them; rough, since longer calls are preempted more often), median over the
photos. Printed only (no results file).
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def child(src: Path, data: Path, repeats: int):
    for package in ('robot_bridge', 'flex_ident', 'rod_deploy'):
        sys.path.insert(0, str(src / 'ros_ws' / 'src' / package))
    import cv2
    from rod_deploy.perception.pipeline import perceive
    out = {}
    for f in sorted(glob.glob(str(data / 'mBEST' / '*.jpg'))):
        img = cv2.imread(f)
        perceive(img)
        calls = []
        for _ in range(repeats):
            r0 = resource.getrusage(resource.RUSAGE_THREAD)
            t0, c0 = time.perf_counter(), time.thread_time()
            perceive(img)
            t1, c1 = time.perf_counter(), time.thread_time()
            r1 = resource.getrusage(resource.RUSAGE_THREAD)
            calls.append(((t1 - t0) * 1e3, (c1 - c0) * 1e3, r1.ru_nivcsw - r0.ru_nivcsw))
        out[Path(f).stem] = calls
    print(json.dumps(out))


def main():
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--other', help='root of another checkout (e.g. main exported with git archive)')
    p.add_argument('--rounds', type=int, default=4)
    p.add_argument('--repeats', type=int, default=25)
    p.add_argument('--data', default=str(ROOT.parent / 'shared' / 'data' / 'dlo_images'))
    p.add_argument('--child', help=argparse.SUPPRESS)
    args = p.parse_args()
    data = Path(args.data)
    if args.child:
        child(Path(args.child), data, args.repeats)
        return
    trees = {'this': ROOT}
    if args.other:
        trees['other'] = Path(args.other).resolve()
    runs = {k: [] for k in trees}
    load_start = os.getloadavg()
    env = dict(os.environ, PYTHONPATH='')
    for r in range(args.rounds):
        for name in (list(trees) if r % 2 == 0 else list(trees)[::-1]):
            cmd = [sys.executable, __file__, '--child', str(trees[name]), '--data', str(data),
                   '--repeats', str(args.repeats)]
            done = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=str(trees[name]))
            if done.returncode != 0:
                sys.exit(f'perception_unpreempted: error: the {name} checkout failed: {done.stderr.strip()[-500:]}')
            runs[name].append(json.loads(done.stdout.strip().splitlines()[-1]))
    load_end = os.getloadavg()
    images = list(runs['this'][0])
    print(f'{args.rounds} rounds x {args.repeats} calls per image and checkout; load average at the start '
          f'{", ".join(f"{v:.1f}" for v in load_start)}, at the end {", ".join(f"{v:.1f}" for v in load_end)}')
    header = '| image |' + ''.join(f' {n}: unpreempted calls | {n}: their median wall ms | {n}: all calls median '
                                   f'wall ms | {n}: median thread CPU ms |' for n in trees)
    print(header)
    print('|---|' + '---|---|---|---|' * len(trees))
    summary = {n: [] for n in trees}
    intercepts = {n: [] for n in trees}
    for im in images:
        row = f'| {im} |'
        for n in trees:
            calls = np.array([c for run in runs[n] for c in run[im]])
            free = calls[calls[:, 2] == 0]
            med = float(np.median(free[:, 0])) if len(free) else float('nan')
            summary[n].append(med)
            fit = np.linalg.lstsq(np.stack([np.ones(len(calls)), calls[:, 2]], axis=1), calls[:, 1], rcond=None)[0]
            intercepts[n].append(float(fit[0]))
            row += (f' {len(free)}/{len(calls)} | {med:.1f} | {np.median(calls[:, 0]):.1f} | '
                    f'{np.median(calls[:, 1]):.1f} |')
        print(row)
    for n in trees:
        free = [v for v in summary[n] if np.isfinite(v)]
        print(f'{n}: median over the images of the unpreempted calls\' median wall clock '
              + (f'{np.median(free):.1f} ms ({len(free)} images)' if free else '- (no call escaped preemption)')
              + f'; thread CPU time extrapolated to no preemption {np.median(intercepts[n]):.1f} ms (median over '
              'the images)')


if __name__ == '__main__':
    main()
