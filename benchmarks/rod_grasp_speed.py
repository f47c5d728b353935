"""Benchmark: optimal-grasp solver speed (cold grasp, continuation step, 200-node pattern); medians.

Targets (issue 4, 2 cores): <= 0.5 s per cold grasp, <= 0.1 s per continuation step, <= 60 s per 200-node pattern.
Published numeric solver: 10-20 s per grasp (paper), 4.9 s cold / 3.5 s per continuation step (released C++ code,
measured on this machine kind), 666-4777 s per 100-200-node pattern (paper Table 3).

The pattern is the released planner's input sequence for the letter U (190 nodes, ../shared reference outputs)
extended to 200 nodes, or a synthetic sine pattern when the reference is absent.  Usage:
    python benchmarks/rod_grasp_speed.py [--repeat 5] [--out benchmarks/results/rod_grasp_speed.md]
"""
import argparse
import os
import platform
import statistics
import time

import numpy as np

from results_dir import add_results_argument, results_path
from rod_deploy.planning.optimal_grasp import grasp_sequence, optimal_grasp

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NN_IO = os.path.join(os.path.dirname(ROOT), 'shared', 'reference', 'rod_deployment', 'reference_outputs',
                     'letterU_nn_io.txt')
COLD_POINTS = [(13.68, 0.0, 2087.0), (13.68, 0.2, 2087.0), (5.0, 1.0, 500.0), (26.0, 0.5, 1156.0),
               (2.0, 0.3, 8000.0), (50.0, 2.0, 3000.0), (9.3, 0.9, 1156.0)]


def pattern_inputs(n=200):
    if os.path.exists(NN_IO):
        d = np.loadtxt(NN_IO, comments='#')[:, :3]
        if len(d) < n:                                   # extend the tail with the last curvature, shorter ls
            extra = np.repeat(d[-1:], n - len(d), axis=0)
            step = d[-1, 0] - d[-2, 0]
            extra[:, 0] = d[-1, 0] + step * np.arange(1, n - len(d) + 1)
            d = np.vstack([d, extra])
        return d[:n], 'letter U (released planner inputs, 190 nodes + 10)'
    i = np.arange(n)
    return np.column_stack([26.0 - 0.1 * i, np.full(n, 1156.0), 0.5 * np.abs(np.sin(0.05 * i))]), 'synthetic sine'


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--repeat', type=int, default=5)
    ap.add_argument('--out', default=None, help='results file (default: see --commit-results)')
    add_results_argument(ap)
    a = ap.parse_args()
    a.out = a.out or str(results_path(a, 'rod_grasp_speed.md'))
    optimal_grasp(5.0, 0.1, 1000.0)                      # warm imports and caches once

    rows = []
    cold_plain, cold_stab = [], []
    for p in COLD_POINTS:
        t1 = statistics.median(timed(lambda: optimal_grasp(*p, check_stability=False))[0] for _ in range(a.repeat))
        t2 = statistics.median(timed(lambda: optimal_grasp(*p, check_stability=True))[0] for _ in range(a.repeat))
        cold_plain.append(t1)
        cold_stab.append(t2)
        rows.append(f'| ({p[0]}, {p[1]}, {p[2]:.0f}) | {t1:.3f} | {t2:.3f} |')

    # continuation steps: the released solver's kappa ramp 0 -> 0.2 in 0.01 steps at (13.68, 2087)
    prev = optimal_grasp(13.68, 0.0, 2087.0, check_stability=False)
    steps = []
    for k in np.arange(0.01, 0.2001, 0.01):
        dt, prev = timed(lambda: optimal_grasp(13.68, float(k), 2087.0, guess=prev, check_stability=False))
        steps.append(dt)
    steps_stab = []
    prev = optimal_grasp(13.68, 0.0, 2087.0, check_stability=False)
    for k in np.arange(0.01, 0.2001, 0.01):
        dt, prev = timed(lambda: optimal_grasp(13.68, float(k), 2087.0, guess=prev, check_stability=True))
        steps_stab.append(dt)

    # a fresh Python process: imports + one cold grasp with the stability check, as the CLI runs it
    import subprocess
    import sys
    code = ('import time; t0 = time.perf_counter(); from rod_deploy.planning.optimal_grasp import optimal_grasp; '
            'g = optimal_grasp(13.68, 0.0, 2087.0); print(time.perf_counter() - t0)')
    fresh = []
    for _ in range(3):
        t0 = time.perf_counter()
        inner = float(subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                                     check=True).stdout)
        fresh.append((time.perf_counter() - t0, inner))
    fresh_wall = statistics.median(f[0] for f in fresh)
    fresh_inner = statistics.median(f[1] for f in fresh)

    inputs, what = pattern_inputs(200)
    pat = []
    for _ in range(max(1, a.repeat // 2)):
        dt, seq = timed(lambda: grasp_sequence(inputs, check_stability=False))
        pat.append(dt)
    dt_stab, seq_stab = timed(lambda: grasp_sequence(inputs, check_stability=True))
    n_unstable = sum(1 for g in seq_stab if not g.stable)

    cpu = platform.processor() or platform.machine()
    try:
        with open('/proc/cpuinfo') as f:
            cpu = next(line.split(':', 1)[1].strip() for line in f if line.startswith('model name'))
    except (OSError, StopIteration):
        pass
    md = [
        '# Optimal-grasp solver speed',
        '',
        f'Machine: {cpu}, {os.cpu_count()} cores, Python {platform.python_version()}; one process, medians of '
        f'{a.repeat} runs.  Produced by `python benchmarks/rod_grasp_speed.py`.',
        '',
        '| measure | ours (BVP) | ours + stability check | target | released numeric solver |',
        '|---|---|---|---|---|',
        f'| cold grasp (median of {len(COLD_POINTS)} points) | {statistics.median(cold_plain):.3f} s | '
        f'{statistics.median(cold_stab):.3f} s | <= 0.5 s | 4.9 s (C++, measured); 10-20 s (paper) |',
        f'| continuation step (kappa 0 -> 0.2 by 0.01 at ls 13.68) | {statistics.median(steps):.3f} s | '
        f'{statistics.median(steps_stab):.3f} s | <= 0.1 s | 3.5 s (C++, measured) |',
        f'| 200-node pattern ({what}) | {statistics.median(pat):.1f} s | {dt_stab:.1f} s | <= 60 s | '
        '666-4777 s for 101-194 nodes (paper Table 3) |',
        '',
        f'A fresh Python process (interpreter start, numpy/scipy imports, one cold grasp with the stability check '
        f'at (13.68, 0, 2087)): {fresh_wall:.2f} s wall, of which {fresh_inner:.2f} s from the first import to the '
        'answer.',
        '',
        'Cold grasps, seconds (ls_bar, kappa_bar, ks_bar): without / with the elastic-stability check',
        '',
        '| point | solve | solve + stability |',
        '|---|---|---|',
        *rows,
        '',
        f'Stability check along the pattern: {n_unstable} of {len(seq_stab)} grasps flagged unstable.',
        f'Slowest continuation step: {max(steps):.3f} s; slowest cold point: {max(cold_plain):.3f} s.',
        '',
    ]
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, 'w') as f:
        f.write('\n'.join(md))
    print('\n'.join(md))


if __name__ == '__main__':
    main()
