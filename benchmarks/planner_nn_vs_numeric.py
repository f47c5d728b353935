"""The network planner against the numeric one along whole patterns, per rod: the gripper paths they plan.

    python benchmarks/planner_nn_vs_numeric.py [--rods 1,3] [--patterns circle,letterA,...] [--commit-results]

For each rod of the paper's Table 1 and each pattern (the paper's 7 by default): both planners with their defaults
(friction-limited start, medium friction), the per-node inputs' range (ls_bar up to L / L_gb: 49 for rod #1, the
network's trained range 0.5-100) and the difference of the planned gripper poses at the same nodes: position (mean,
max, mm) and orientation (max, degrees).
"""
from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from deployment_table import RODS, all_patterns
from results_dir import add_results_argument, results_path
from rod_deploy.deployment.simulate import FRICTION_LEVELS
from rod_deploy.planning.neural_controller import load_grasp_network
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rods', default='1,3')
    ap.add_argument('--patterns', default='circle,letterA,letterC,letterL,letterU,line,sine')
    add_results_argument(ap)
    args = ap.parse_args()
    patterns = all_patterns(args.patterns)
    trained = load_grasp_network().trained_range
    mu = FRICTION_LEVELS['medium']
    rows = []
    t_all = time.perf_counter()
    for rod_id in (int(r) for r in args.rods.split(',')):
        rod = rod_description_from_dict(RODS[rod_id])
        for name, P in patterns.items():
            plans = {}
            for method in ('nn', 'numeric'):
                t0 = time.perf_counter()
                plans[method] = (plan_trajectory(P, rod, PlannerSettings(method=method, friction=mu)),
                                 time.perf_counter() - t0)
            (a, ta), (b, tb) = plans['nn'], plans['numeric']
            dp = 1000 * np.linalg.norm(a.position - b.position, axis=1)
            ang = np.degrees((a.rotation.inv() * b.rotation).magnitude())
            ls = a.inputs[:, 0]
            rows.append((rod_id, name, ls.min(), ls.max(), np.abs(a.inputs[:, 2]).max(), dp.mean(), dp.max(),
                         ang.max(), ta, tb))
            print(f'rod #{rod_id} {name:8s} ls_bar {ls.min():.1f}-{ls.max():.1f}: gripper nn - numeric mean '
                  f'{dp.mean():.3f} mm, max {dp.max():.3f} mm, orientation max {ang.max():.3f} deg '
                  f'(plan {ta:.2f} s / {tb:.1f} s)', flush=True)
    out = results_path(args, 'planner_nn_vs_numeric.md')
    lines = ['# Network vs numeric planner along whole patterns: `python benchmarks/planner_nn_vs_numeric.py '
             f'--rods {args.rods}`', '',
             f'{platform.machine()}, {os.cpu_count()} cores (shared), {time.perf_counter() - t_all:.0f} s in all. '
             'Both planners with their defaults (friction-limited start, mu 0.5); the gripper poses compared at the '
             f'same nodes. The network\'s trained range: ls_bar {trained["ls_bar"]}, ks_bar {trained["ks_bar"]}, '
             f'|kappa_bar| {trained["abs_kappa_bar"]} (inputs outside it are refused).', '',
             '| rod | pattern | ls_bar | max abs kappa_bar | position mean mm | position max mm | orientation max deg '
             '| plan s nn / numeric |', '|' + '---|' * 8]
    for r in rows:
        lines.append(f'| #{r[0]} | {r[1]} | {r[2]:.1f}-{r[3]:.1f} | {r[4]:.3f} | {r[5]:.3f} | {r[6]:.3f} | '
                     f'{r[7]:.3f} | {r[8]:.2f} / {r[9]:.1f} |')
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


if __name__ == '__main__':
    main()
