"""Where the error of a sharply bent pattern comes from (issue #10): what the planner changes on purpose (the
friction-limited start, the curvature rate limit) against what the rod does after touching down.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/tight_bend_decomposition.py \
        [--cases zigzag_rounded:rod3,letterA:rod3,long_wave_1p5m:cable] [--planned-curves spread,closest] \
        [--commit-results]

Per case and planned curve, Eq. 17 e_mean [cm] (N = 50) of: the start-replaced pattern (the friction-limited start
only) against the pattern; the curve the grasps ask for (``PlannedTrajectory.asked_xy``: the planned curvature
integrated from the free end) against the pattern; the deployed rod (our DER, friction 0.5, the defaults of
``rod-deploy simulate``, nodes recorded every second) against the pattern and against the asked curve. Then, along
the rod (error_profile.py's reading): the mean error at touch-down and the mean motion on the table after it [mm].
Shapes: the acceptance rehearsal's (``acceptance_rehearsal.shapes``) and the deployment table's patterns.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402


def rod_for(name):
    from acceptance_rehearsal import RODS as REHEARSAL_RODS
    from deployment_table import RODS
    from rod_deploy.planning.rod_description import rod_description_from_dict
    d = dict(RODS[int(name[3:])]) if name.startswith('rod') else dict(REHEARSAL_RODS[name])
    return rod_description_from_dict({**d, 'friction': 0.5})


def pattern_for(name):
    from acceptance_rehearsal import shapes
    from deployment_table import all_patterns
    sh = shapes()
    return (sh[name][0] if name in sh else all_patterns(name)[name])[:, :2]


def main():
    from error_profile import profile
    from replay_probe import run_der
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--cases', default='zigzag_rounded:rod3,letterA:rod3,long_wave_1p5m:cable')
    ap.add_argument('--planned-curves', default='spread,closest')
    ap.add_argument('--out-name', default='tight_bend_decomposition.md')
    add_results_argument(ap)
    args = ap.parse_args()
    out = results_path(args, args.out_name)
    rows, t_all = [], time.perf_counter()
    for case in args.cases.split(','):
        name, rod_name = case.split(':')
        P, rod = pattern_for(name), rod_for(rod_name)
        for pc in args.planned_curves.split(','):
            plan = plan_trajectory(P, rod, PlannerSettings(planned_curve=pc, friction=0.5))
            G = plan.drawn_pattern.xy
            start_xy = (plan.start_pattern if plan.start_pattern is not None else plan.pattern).xy
            times, nodes, deployed, t_rel, desc = run_der((plan.t, plan.position, plan.quaternion, None), rod, 0.5,
                                                          {}, 1.0)
            npz = out.parent / f'_decomp_{name}_{pc}.npz'
            np.savez(npz, times=times, nodes=nodes, pattern=P, deployed=deployed,
                     e_mean_cm=eq17_error(P, deployed)['e_mean_cm'])
            prof = profile(npz, rod.radius_m, rod.gravito_bending_length_m)
            npz.unlink()
            rows.append((name, rod_name, pc, eq17_error(G, start_xy)['e_mean_cm'],
                         eq17_error(G, plan.asked_xy)['e_mean_cm'], eq17_error(P, deployed)['e_mean_cm'],
                         eq17_error(plan.asked_xy, deployed)['e_mean_cm'], 1e3 * prof['err_touch'].mean(),
                         1e3 * prof['moved'].mean(), 100 * plan.asked_deviation()[0]))
            print(rows[-1], flush=True)
            write(out, rows, t_all)
    print(f'results: {out}')


def write(out, rows, t_all):
    lines = ['# Error decomposition of sharply bent patterns, `python benchmarks/tight_bend_decomposition.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{os.getloadavg()[0]:.1f} at writing); {time.perf_counter() - t_all:.0f} s in all. Friction 0.5, our '
             'DER (defaults of `rod-deploy simulate`), planner nn with the friction-limited start. Eq. 17 e_mean in '
             'cm; touch-down error and motion after touch-down: means over the rod\'s laid nodes (error_profile.py).',
             '', '| pattern | rod | planned curve | start-replaced vs pattern | asked curve vs pattern | deployed vs '
             'pattern | deployed vs asked curve | error at touch-down mm | moved after touch-down mm | asked curve '
             'max off cm |', '|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        lines.append(f'| {r[0]} | {r[1]} | {r[2]} | {r[3]:.3f} | {r[4]:.3f} | {r[5]:.3f} | {r[6]:.3f} | {r[7]:.1f} '
                     f'| {r[8]:.1f} | {r[9]:.1f} |')
    out.write_text('\n'.join(lines) + '\n')


if __name__ == '__main__':
    main()
