"""Before / after CPU time of `perceive` on the published mBEST photos, the two versions run in turns.

    .venv/bin/python benchmarks/perception_speed_ab.py --before /tmp/old/ros_ws/src/rod_deploy [--rounds 6]
                                                       [--repeats 10] [--before-name TEXT]
                                                       [--commit-results]

``--before``: the rod_deploy package folder of another checkout (e.g. ``git archive <commit> ros_ws/src/rod_deploy
| tar -x -C /tmp/old``; its numba kernels compile into its own folder on the first round). Each round runs one
process per version, alternating (so both see the same machine load), each timing every photo ``--repeats`` times
(image in memory, kernels loaded, one warm-up run per photo first) by process CPU time (all threads) and the wall
clock. The table gives, per version, the median over all runs of all rounds and the median of the per-round medians'
spread, and the load average at the start and end; the difference is the after version's median minus the before's.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from results_dir import add_results_argument, results_path

ROOT = Path(__file__).resolve().parent.parent
AFTER = ROOT / 'ros_ws' / 'src' / 'rod_deploy'
RUN = '''
import glob, json, sys, time
import cv2
import rod_deploy.perception.pipeline as pipeline
files = sorted(glob.glob(sys.argv[1] + '/mBEST/*.jpg'))
images = [cv2.imread(f) for f in files]
for img in images:
    pipeline.perceive(img)
cpu, wall = [], []
for _ in range(int(sys.argv[2])):
    for img in images:
        c0, t0 = time.process_time(), time.perf_counter()
        pipeline.perceive(img)
        cpu.append((time.process_time() - c0) * 1e3)
        wall.append((time.perf_counter() - t0) * 1e3)
print(json.dumps({'cpu': cpu, 'wall': wall, 'module': pipeline.__file__}))
'''


def run(package: Path, data: Path, repeats: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(package))
    out = subprocess.run([sys.executable, '-c', RUN, str(data), str(repeats)], env=env, capture_output=True,
                         text=True, check=True)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if not result['module'].startswith(str(package)):
        raise SystemExit(f'{package}: imported {result["module"]} instead (is it a rod_deploy package folder?)')
    return result


def main():
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--before', type=Path, required=True, help='rod_deploy package folder of the old checkout')
    p.add_argument('--after', type=Path, default=AFTER, help='... of the new one (default: this checkout)')
    p.add_argument('--before-name', default=None, help='what the old version is (e.g. its commit), for the table')
    p.add_argument('--data', type=Path, default=ROOT.parent / 'shared' / 'data' / 'dlo_images')
    p.add_argument('--rounds', type=int, default=6)
    p.add_argument('--repeats', type=int, default=10)
    add_results_argument(p)
    args = p.parse_args()
    versions = {'before': args.before.resolve(), 'after': args.after.resolve()}
    names = {'before': args.before_name or str(versions['before']), 'after': str(versions['after'])}
    runs = {name: [] for name in versions}
    load_start = os.getloadavg()
    for k in range(args.rounds):
        for name, package in versions.items():
            r = run(package, args.data, args.repeats)
            runs[name].append(r)
            print(f'round {k + 1}: {name} CPU median {np.median(r["cpu"]):.2f} ms, wall {np.median(r["wall"]):.2f} ms, '
                  f'load {os.getloadavg()[0]:.1f}', flush=True)
    load_end = os.getloadavg()
    lines = ['# Perception CPU time before / after (`benchmarks/perception_speed_ab.py`)', '',
             f'{args.rounds} rounds, each one process per version in turn, {args.repeats} runs of each of the mBEST '
             f'photos per process (`{args.data.name}/mBEST`); {os.cpu_count()} logical CPUs, load average at the '
             f'start {", ".join(f"{v:.1f}" for v in load_start)}, at the end '
             f'{", ".join(f"{v:.1f}" for v in load_end)}. Process CPU time (all threads) per image.', '',
             '| version | package | CPU ms median | CPU ms mean | per-round CPU medians (min - max) | '
             'wall ms median |', '|---|---|---|---|---|---|']
    medians = {}
    for name, package in versions.items():
        cpu = np.concatenate([r['cpu'] for r in runs[name]])
        wall = np.concatenate([r['wall'] for r in runs[name]])
        per_round = [np.median(r['cpu']) for r in runs[name]]
        medians[name] = float(np.median(cpu))
        lines.append(f'| {name} | {names[name]} | {medians[name]:.2f} | {np.mean(cpu):.2f} | '
                     f'{min(per_round):.2f} - {max(per_round):.2f} | {np.median(wall):.2f} |')
    wins = sum(np.median(a['cpu']) < np.median(b['cpu']) for a, b in zip(runs['after'], runs['before']))
    lines += ['', f'After minus before: {medians["after"] - medians["before"]:+.2f} ms CPU median per image '
              f'({100 * (medians["after"] / medians["before"] - 1):+.1f} %); the after version had the lower median '
              f'in {wins} of {args.rounds} rounds.', '']
    text = '\n'.join(lines)
    out = results_path(args, 'perception_speed_ab.md')
    out.write_text(text)
    print(text)


if __name__ == '__main__':
    main()
