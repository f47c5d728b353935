"""Perception speed side by side: this checkout's ``perceive`` against another checkout's (e.g. main's), on
the published mBEST photos, in alternating processes so that the load of a shared machine hits both alike.

    python benchmarks/perception_side_by_side.py --other /tmp/main_src [--rounds 6] [--repeats 5]
                                                 [--data ../shared/data/dlo_images] [--commit-results]

``--other`` is the root of another checkout of this repository (e.g. ``git archive main | tar -x -C DIR``).
Each round runs one process per checkout (the order alternates from round to round); a process loads the
images, calls ``perceive`` once per image (compilation, caches), then times ``--repeats`` calls per image
(wall clock and process CPU time, image in memory, segmentation to ordered paths, as
``perception_mbest.py``; the pipeline's per-stage timer is made to read CPU time). Reported per image: the
median over all rounds of each checkout, and the per-stage CPU medians; and how far the two checkouts' paths lie apart (largest distance from a point of one
to the other's nearest path point, over the objects matched by order). Accuracy against the ground truth
is ``perception_mbest.py``'s job.
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from results_dir import add_results_argument, results_path

ROOT = Path(__file__).resolve().parent.parent


def child(src: Path, data: Path, repeats: int):
    """Time ``perceive`` of the checkout at ``src``; print one JSON line."""
    for package in ('robot_bridge', 'flex_ident', 'rod_deploy'):
        sys.path.insert(0, str(src / 'ros_ws' / 'src' / package))
    import types

    import cv2
    from rod_deploy.perception import pipeline
    # the pipeline's stage timer reads the process CPU time here: per-stage CPU, not wall clock
    pipeline.time = types.SimpleNamespace(perf_counter=time.process_time)
    perceive = pipeline.perceive
    files = sorted(glob.glob(str(data / 'mBEST' / '*.jpg')))
    out = {}
    for f in files:
        img = cv2.imread(f)
        res = perceive(img)
        wall, cpu, stages = [], [], {}
        for _ in range(repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            r = perceive(img)
            wall.append((time.perf_counter() - t0) * 1e3)
            cpu.append((time.process_time() - c0) * 1e3)
            for k, v in r.timings_ms.items():
                stages.setdefault(k, []).append(v)
        out[Path(f).stem] = dict(wall=wall, cpu=cpu, stages=stages,
                                 paths=[o.points.tolist() for o in res.objects])
    print(json.dumps(out))


def path_gap(a, b) -> float:
    """Largest distance [px] from a point of either path set to the nearest point of the other."""
    if len(a) != len(b):
        return float('inf')
    worst = 0.0
    for p, q in zip(a, b):
        p, q = np.asarray(p), np.asarray(q)
        d = np.linalg.norm(p[:, None, :] - q[None, :, :], axis=2)
        worst = max(worst, float(d.min(axis=1).max()), float(d.min(axis=0).max()))
    return worst


def main():
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--other', help='root of the other checkout (e.g. main exported with git archive)')
    p.add_argument('--rounds', type=int, default=6)
    p.add_argument('--repeats', type=int, default=5)
    p.add_argument('--data', default=str(ROOT.parent / 'shared' / 'data' / 'dlo_images'))
    p.add_argument('--child', help=argparse.SUPPRESS)
    add_results_argument(p)
    args = p.parse_args()
    data = Path(args.data)
    if args.child:
        child(Path(args.child), data, args.repeats)
        return
    if not args.other or not (Path(args.other) / 'ros_ws' / 'src' / 'rod_deploy').is_dir():
        sys.exit('perception_side_by_side: error: --other must be the root of another checkout of this repository')
    if not glob.glob(str(data / 'mBEST' / '*.jpg')):
        sys.exit(f'perception_side_by_side: error: no mBEST photos in {data / "mBEST"}')
    trees = {'this': ROOT, 'other': Path(args.other).resolve()}
    runs = {k: [] for k in trees}
    load_start = os.getloadavg()
    env = dict(os.environ, PYTHONPATH='')          # each child puts only its own checkout on the path
    for r in range(args.rounds):
        for name in (('this', 'other') if r % 2 == 0 else ('other', 'this')):
            cmd = [sys.executable, __file__, '--child', str(trees[name]), '--data', str(data),
                   '--repeats', str(args.repeats)]
            done = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=str(trees[name]))
            if done.returncode != 0:
                sys.exit(f'perception_side_by_side: error: the {name} checkout failed: '
                         f'{done.stderr.strip().splitlines()[-1] if done.stderr.strip() else done.returncode}')
            runs[name].append(json.loads(done.stdout.strip().splitlines()[-1]))
            print(f'round {r + 1}/{args.rounds} {name} done, load {os.getloadavg()[0]:.1f}', flush=True)
    load_end = os.getloadavg()
    images = list(runs['this'][0])

    def pooled(name, image, key):
        return [v for run in runs[name] for v in run[image][key]]

    def stage(name, image, key):
        return float(np.median([v for run in runs[name] for v in run[image]['stages'].get(key, [])] or [np.nan]))

    stages = [k for k in runs['this'][0][images[0]]['stages'] if k != 'total']
    lines = ['# Perception speed side by side (`benchmarks/perception_side_by_side.py`)', '',
             __doc__.split('\n\n')[2].strip().replace('\n', ' '), '',
             f'This checkout: {ROOT.name}; other: {args.other}. {args.rounds} rounds x {args.repeats} runs per image '
             f'and checkout; {os.cpu_count()} CPUs, load average at the start '
             f'{", ".join(f"{v:.1f}" for v in load_start)}, at the end {", ".join(f"{v:.1f}" for v in load_end)} '
             '(a loaded machine inflates both wall clock and CPU time; compare the two columns, not the '
             'absolute numbers).', '',
             '| image | wall ms this | wall ms other | CPU ms this | CPU ms other | CPU ratio | paths apart px |',
             '|---|---|---|---|---|---|---|']
    summary = {k: [] for k in ('wt', 'wo', 'ct', 'co')}
    for im in images:
        wt, wo = np.median(pooled('this', im, 'wall')), np.median(pooled('other', im, 'wall'))
        ct, co = np.median(pooled('this', im, 'cpu')), np.median(pooled('other', im, 'cpu'))
        for k, v in zip(summary, (wt, wo, ct, co)):
            summary[k].append(v)
        gap = path_gap(runs['this'][0][im]['paths'], runs['other'][0][im]['paths'])
        lines.append(f'| {im} | {wt:.1f} | {wo:.1f} | {ct:.1f} | {co:.1f} | {ct / co:.2f} | {gap:.2f} |')
    med = {k: float(np.median(v)) for k, v in summary.items()}
    lines += ['', f"Median over the images: wall clock {med['wt']:.1f} ms (this) against {med['wo']:.1f} ms (other), "
              f"CPU {med['ct']:.1f} ms against {med['co']:.1f} ms ({100 * (med['ct'] / med['co'] - 1):+.0f} %).", '',
              '## CPU per stage (median over runs, then over images) [ms]', '',
              '| stage | this | other |', '|---|---|---|']
    for s in stages:
        t = np.median([stage('this', im, s) for im in images])
        o = np.median([stage('other', im, s) for im in images])
        lines.append(f'| {s} | {t:.2f} | {o:.2f} |')
    lines.append('')
    out = results_path(args, 'perception_side_by_side.md')
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))
    print(f'wrote {out}')


if __name__ == '__main__':
    main()
