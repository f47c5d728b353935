"""Accuracy and speed of the shipped grasp network against fresh numeric solves it was never trained on.

    python benchmarks/grasp_network_accuracy.py [--samples 200] [--seed 1] [--commit-results]

Fresh optimal grasps (continuum convention, ``optimal_grasp``) at random inputs in the planner's region for the
paper's rods (ls_bar 0.5-28, ks_bar 600-3000, |kappa_bar| 0-1.5, both signs) and over the whole trained range;
position error in mm for L_gb = 3.3 cm, orientation error in degrees (angle of R_pred^T R_true). Also the
network along the 7 published patterns (their per-node inputs, read in place when ../shared is present) against the
numeric solver with continuation, and the time of a 200-node prediction.
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from results_dir import add_results_argument, results_path
from rod_deploy.planning.neural_controller import load_grasp_network
from rod_deploy.planning.optimal_grasp import grasp_sequence, optimal_grasp

REF = Path(__file__).resolve().parents[2] / 'shared' / 'reference' / 'rod_deployment'
LGB_MM = 33.0


def errors(net, inputs, position, rotvec):
    p, r = net.predict(inputs[:, 0], inputs[:, 1], inputs[:, 2])
    pos_mm = np.linalg.norm(p - position, axis=1) * LGB_MM
    ang = (Rotation.from_rotvec(r).inv() * Rotation.from_rotvec(rotvec)).magnitude()
    return pos_mm, np.degrees(ang)


def fresh(rng, n, ls, ks, kap):
    rows, pos, rot = [], [], []
    while len(rows) < n:
        x = (np.exp(rng.uniform(np.log(ls[0]), np.log(ls[1]))), np.exp(rng.uniform(np.log(ks[0]), np.log(ks[1]))),
             rng.uniform(-kap, kap))
        try:
            g = optimal_grasp(x[0], x[2], x[1], check_stability=False)
        except Exception:   # noqa: BLE001 - a point the solver cannot do is skipped and counted
            continue
        rows.append(x)
        pos.append(g.position)
        rot.append(g.rotvec)
    return np.array(rows), np.array(pos), np.array(rot)


def summary(name, pos_mm, ang):
    return (f'| {name} | {len(pos_mm)} | {np.mean(pos_mm):.3f} | {np.median(pos_mm):.3f} | '
            f'{np.percentile(pos_mm, 95):.3f} | {np.max(pos_mm):.3f} | {np.mean(ang):.4f} | {np.max(ang):.4f} |')


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--samples', type=int, default=200)
    ap.add_argument('--seed', type=int, default=1)
    add_results_argument(ap)
    args = ap.parse_args()
    net = load_grasp_network()
    rng = np.random.default_rng(args.seed)
    lines = ['# Grasp network accuracy (`python benchmarks/grasp_network_accuracy.py`)', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores. Network: {net.record.get("width")} x '
             f'{net.record.get("depth")} {net.record.get("activation")}, trained in {net.record.get("train_time_s")} s '
             f'(`scripts/train_grasp_network.py`). Errors against fresh numeric solves at random inputs (never '
             f'trained on); position in mm for L_gb = {LGB_MM / 10:.1f} cm, orientation in degrees.', '',
             '| inputs | n | position MAE mm | median | 95 % | max | orientation mean deg | max |',
             '|---|---|---|---|---|---|---|---|']
    t0 = time.perf_counter()
    sets = {'planner region (ls 0.5-28, ks 600-3000, |kappa| <= 1.5)': ((0.5, 28.0), (600.0, 3000.0), 1.5),
            'whole trained range (ls 0.5-100, ks 200-20000, |kappa| <= 4)': ((0.5, 100.0), (200.0, 20000.0), 4.0)}
    for name, (ls, ks, kap) in sets.items():
        x, p, r = fresh(rng, args.samples, ls, ks, kap)
        lines.append(summary(name, *errors(net, x, p, r)))
    solve_s = time.perf_counter() - t0
    patterns = sorted(REF.glob('reference_outputs/*_nn_io.txt')) if REF.exists() else []
    if patterns:
        lines += ['', 'Along the 7 published patterns (their per-node inputs: ls_bar from 26.2 down, ks_bar 1156), '
                      'network vs the numeric solver with curvature continuation:', '',
                  '| pattern | nodes | position MAE mm | median | 95 % | max | orientation mean deg | max |',
                  '|---|---|---|---|---|---|---|---|']
        for f in patterns:
            io = np.loadtxt(f)
            seq = grasp_sequence(io[:, :3])
            p = np.array([g.position for g in seq])
            r = np.array([g.rotvec for g in seq])
            lines.append(summary(f.name.replace('_nn_io.txt', ''), *errors(net, io[:, :3], p, r)))
    x = np.column_stack([np.linspace(26, 12, 200), np.full(200, 1156.0), np.linspace(0, 1, 200)])
    times = []
    for _ in range(50):
        t1 = time.perf_counter()
        net.predict(x[:, 0], x[:, 1], x[:, 2])
        times.append(time.perf_counter() - t1)
    lines += ['', f'200-node prediction: median {1000 * np.median(times):.3f} ms (50 runs, numpy, in-process). '
                  f'Fresh solves took {solve_s:.0f} s.']
    out = results_path(args, 'grasp_network_accuracy.md')
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))
    print(f'results: {out}')


if __name__ == '__main__':
    main()
