"""Does a coarser DER in the refinement loop transfer? ``refine_plan`` run with a coarse simulator (edges
``--edge`` m, step ``--dt`` s), the kept trajectory then simulated once with the default (fine) one and scored with
Eq. 17, against the fine loop's numbers in ``deployment_table_drag_rod3_medium_refined.md``.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/refine_coarse.py [--patterns letterA,letterL] \
        [--edge 0.01] [--dt 0.04] [--simulations 5] [--commit-results]
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402


def main():
    from deployment_table import RODS, all_patterns
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.deployment.refinement import RefinementSettings, refine_plan
    from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--patterns', default='letterA,letterL')
    ap.add_argument('--edge', type=float, default=0.01)
    ap.add_argument('--dt', type=float, default=0.04)
    ap.add_argument('--simulations', type=int, default=5, help='coarse simulations, the unrefined plan\'s included')
    add_results_argument(ap)
    args = ap.parse_args()
    rod = rod_description_from_dict({**RODS[3], 'friction': 0.5})
    fine = SimulationSettings(friction=0.5)
    coarse = SimulationSettings(friction=0.5, edge_length_m=args.edge, dt_s=args.dt)
    rows = []
    for name, P in all_patterns(args.patterns).items():
        planner = PlannerSettings(friction=0.5)
        plan = plan_trajectory(P, rod, planner)
        c0 = time.process_time()
        best, record = refine_plan(P[:, :2], rod, plan, planner, coarse,
                                   RefinementSettings(simulations=args.simulations - 1))
        loop_cpu = time.process_time() - c0
        c0 = time.process_time()
        d = best.deployment
        res = simulate_deployment(d.t, d.position, d.quaternion, rod, fine)
        check_cpu = time.process_time() - c0
        e = eq17_error(P, res.deployed_xy)['e_mean_cm']
        rows.append((name, record['start_predicted_e_mean_cm'], record['predicted_e_mean_cm'], e, loop_cpu,
                     check_cpu))
        print(f'{name}: coarse predicted {rows[-1][1]:.3f} -> {rows[-1][2]:.3f}, fine {e:.3f} cm; CPU loop '
              f'{loop_cpu:.0f} s + check {check_cpu:.0f} s', flush=True)
    lines = [f'# Refinement with a coarse DER, `python benchmarks/refine_coarse.py --edge {args.edge:g} --dt '
             f'{args.dt:g} --simulations {args.simulations}`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{os.getloadavg()[0]:.1f} at the end). Rod #3, friction 0.5, planner nn with the drag compensation; the '
             f'loop simulates with {1000 * args.edge:g} mm edges and dt {args.dt:g} s (the default: 5 mm, 0.02 s); the '
             'kept trajectory is then simulated once with the default simulator (e_mean fine, Eq. 17, cm).', '',
             '| pattern | coarse predicted before | coarse predicted after | e_mean fine | CPU loop s | CPU fine check s |',
             '|---|---|---|---|---|---|']
    for r in rows:
        lines.append(f'| {r[0]} | {r[1]:.3f} | {r[2]:.3f} | {r[3]:.3f} | {r[4]:.0f} | {r[5]:.0f} |')
    out = results_path(args, f'refine_coarse_edge{1000 * args.edge:g}mm.md')
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


if __name__ == '__main__':
    main()
