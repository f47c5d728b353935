"""Does a simulated deployment converge with the time step and the edge length? One pattern, one rod, our default
planner (nn, or ``--method``), the deployment simulated at several dt and rod edge lengths; e_mean (Eq. 17), the
error along the pattern and the Newton statistics of each run.

    python benchmarks/deployment_dt_convergence.py [--rod 1] [--pattern circle] [--dts 0.02,0.01,0.005,0.0025]
                                                   [--edges 0.005,0.0025,0.00125] [--method nn]
                                                   [--settings K=V,..] [--out-name NAME.md] [--commit-results]

Edge lengths: ``SimulationSettings.edge_length_m``; every edge length is run at every dt. The error along the
pattern: the distance between the pattern and the deployed curve at 0, 20, .., 100 % of the pattern's length (Eq.
17's resampling, its better direction).

Newton statistics: iterations per step (mean, max), steps retried as half steps because Newton did not converge
(``halved_steps``; such a step is never accepted), the smallest step taken. Also the laid strain at the end (the deployed
rod's arc length over its material length, minus 1). ``--settings K=V,..``: other SimulationSettings (e.g.
``max_gripper_speed_m_s=0.005``). The "before" results (``*_before.md``) were run at commit b9ecfb5, where the rod's
rest length was still the stretched hanging length.
"""
from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from deployment_table import RODS, all_patterns, laid_strain
from results_dir import add_results_argument, results_path
from rod_deploy.deployment.metrics import N_POINTS, eq17_error, resample
from rod_deploy.deployment.simulate import FRICTION_LEVELS, SimulationSettings, simulate_deployment
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

PROFILE_FRACTIONS = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0)


def error_profile_cm(P, deployed, fractions=PROFILE_FRACTIONS):
    """Distance [cm] between the pattern and the deployed curve at the given fractions of the pattern's length
    (both resampled as Eq. 17 does, N = 50, the deployed curve in the direction Eq. 17 found better)."""
    e = eq17_error(P, deployed)
    d = deployed[::-1] if e['reversed'] else deployed
    a = resample(P, N_POINTS)
    b = resample(d, N_POINTS, length=e['pattern_length_m'])
    dist = 100 * np.linalg.norm(a - b, axis=1)
    return [float(dist[int(round(f * (N_POINTS - 1)))]) for f in fractions]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rod', type=int, default=1)
    ap.add_argument('--pattern', default='circle')
    ap.add_argument('--friction', default='medium')
    ap.add_argument('--method', default='nn', choices=('nn', 'numeric'))
    ap.add_argument('--dts', default='0.02,0.01,0.005,0.0025')
    ap.add_argument('--edges', default=str(SimulationSettings.edge_length_m),
                    help='rod edge lengths [m], comma-separated')
    ap.add_argument('--settings', default='', help='extra SimulationSettings, e.g. "max_gripper_speed_m_s=0.005"')
    ap.add_argument('--out-name', default=None)
    add_results_argument(ap)
    args = ap.parse_args()
    rod = rod_description_from_dict(RODS[args.rod])
    P = all_patterns(args.pattern)[args.pattern]
    mu = FRICTION_LEVELS[args.friction]
    plan = plan_trajectory(P, rod, PlannerSettings(method=args.method, friction=mu))
    extra = {}
    for kv in filter(None, args.settings.split(',')):
        k, v = kv.split('=')
        try:
            extra[k] = float(v)
        except ValueError:
            extra[k] = {'True': True, 'False': False}.get(v, v)
    out = results_path(args, args.out_name or f'deployment_dt_convergence_rod{args.rod}_{args.pattern}.md')
    rows, shapes = [], {}
    t_all = time.perf_counter()
    for edge in (float(v) for v in args.edges.split(',')):
        for dt in (float(v) for v in args.dts.split(',')):
            t0 = time.process_time()
            try:
                res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod,
                                          SimulationSettings(friction=mu, dt_s=dt, edge_length_m=edge, **extra))
                e = eq17_error(P, res.deployed_xy)
                shapes[f'edge{edge:g}_dt{dt:g}'] = res.deployed_xy
                rows.append((edge, dt, e['e_mean_cm'], e['sigma_cm'], res.steps, res.newton_iterations / res.steps,
                             res.max_newton_iterations, res.halved_steps, res.smallest_step_s,
                             100 * laid_strain(res, rod.length_m), time.process_time() - t0,
                             error_profile_cm(P, res.deployed_xy), ''))
            except ValueError as exc:
                rows.append((edge, dt, np.nan, np.nan, 0, np.nan, 0, 0, np.nan, np.nan, time.process_time() - t0,
                             [np.nan] * len(PROFILE_FRACTIONS), str(exc)[:120]))
            r = rows[-1]
            print(f'edge {1000 * r[0]:g} mm, dt {r[1]:g}: e_mean {r[2]:.4f} cm, {r[4]} steps, Newton {r[5]:.2f} per '
                  f'step (max {r[6]}), halved {r[7]}, smallest step {r[8]:g} s, laid strain {r[9]:.2f} %, '
                  f'{r[10]:.0f} s CPU, along the pattern {" ".join(f"{v:.3f}" for v in r[11])} cm {r[12]}',
                  flush=True)
    np.savez_compressed(out.with_suffix('.npz'), pattern=P, **shapes)
    lines = [f'# e_mean vs dt and edge length: rod #{args.rod}, {args.pattern}, {args.friction} friction, '
             f'{args.method} planner', '',
             f'`python benchmarks/deployment_dt_convergence.py --rod {args.rod} --pattern {args.pattern} '
             f'--method {args.method} --dts {args.dts} --edges {args.edges}'
             f'{" --settings " + args.settings if args.settings else ""}`; '
             f'{platform.machine()}, {os.cpu_count()} cores (shared), {time.perf_counter() - t_all:.0f} s in all. '
             'Newton: iterations per step; halved: steps of dt whose Newton did not converge, retried as half '
             'steps (never accepted); laid strain: the deployed arc length over its material length, minus 1; '
             'along the pattern: the distance pattern - deployed at 0, 20, 40, 60, 80, 100 % of the pattern [cm]; '
             'CPU s: process time of the simulation. The deployed shapes: the .npz beside this file.', '',
             '| edge mm | dt s | e_mean cm | sigma cm | along the pattern cm | steps | Newton per step | max | halved '
             '| smallest step s | laid strain % | CPU s | note |', '|' + '---|' * 13]
    for r in rows:
        profile = ' / '.join(f'{v:.2f}' for v in r[11])
        lines.append(f'| {1000 * r[0]:g} | {r[1]:g} | {r[2]:.4f} | {r[3]:.4f} | {profile} | {r[4]} | {r[5]:.2f} | '
                     f'{r[6]} | {r[7]} | {r[8]:g} | {r[9]:.2f} | {r[10]:.0f} | {r[12]} |')
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


if __name__ == '__main__':
    main()
