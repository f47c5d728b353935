"""Does a simulated deployment converge with the time step? One pattern, one rod, our default planner (nn), the
deployment simulated at several dt; e_mean (Eq. 17) and the Newton statistics of each run.

    python benchmarks/deployment_dt_convergence.py [--rod 1] [--pattern circle] [--dts 0.02,0.01,0.005,0.0025]
                                                   [--settings K=V,..] [--out-name NAME.md] [--commit-results]

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
from rod_deploy.deployment.metrics import eq17_error
from rod_deploy.deployment.simulate import FRICTION_LEVELS, SimulationSettings, simulate_deployment
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rod', type=int, default=1)
    ap.add_argument('--pattern', default='circle')
    ap.add_argument('--friction', default='medium')
    ap.add_argument('--dts', default='0.02,0.01,0.005,0.0025')
    ap.add_argument('--settings', default='', help='extra SimulationSettings, e.g. "exact_rest_length=False"')
    ap.add_argument('--out-name', default=None)
    add_results_argument(ap)
    args = ap.parse_args()
    rod = rod_description_from_dict(RODS[args.rod])
    P = all_patterns(args.pattern)[args.pattern]
    mu = FRICTION_LEVELS[args.friction]
    plan = plan_trajectory(P, rod, PlannerSettings(method='nn', friction=mu))
    extra = {}
    for kv in filter(None, args.settings.split(',')):
        k, v = kv.split('=')
        try:
            extra[k] = float(v)
        except ValueError:
            extra[k] = {'True': True, 'False': False}.get(v, v)
    out = results_path(args, args.out_name or f'deployment_dt_convergence_rod{args.rod}_{args.pattern}.md')
    rows = []
    t_all = time.perf_counter()
    for dt in (float(v) for v in args.dts.split(',')):
        t0 = time.process_time()
        try:
            res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod,
                                      SimulationSettings(friction=mu, dt_s=dt, **extra))
            e = eq17_error(P, res.deployed_xy)
            rows.append((dt, e['e_mean_cm'], e['sigma_cm'], res.steps, res.newton_iterations / res.steps,
                         res.max_newton_iterations, res.halved_steps, res.smallest_step_s,
                         100 * laid_strain(res, rod.length_m), time.process_time() - t0, ''))
        except ValueError as exc:
            rows.append((dt, np.nan, np.nan, 0, np.nan, 0, 0, np.nan, np.nan, time.process_time() - t0, str(exc)[:120]))
        r = rows[-1]
        print(f'dt {r[0]:g}: e_mean {r[1]:.4f} cm, {r[3]} steps, Newton {r[4]:.2f} per step (max {r[5]}), halved '
              f'{r[6]}, smallest step {r[7]:g} s, laid strain {r[8]:.2f} %, {r[9]:.0f} s CPU {r[10]}', flush=True)
    lines = [f'# e_mean vs dt: rod #{args.rod}, {args.pattern}, {args.friction} friction, nn default planner', '',
             f'`python benchmarks/deployment_dt_convergence.py --rod {args.rod} --pattern {args.pattern} '
             f'--dts {args.dts}{" --settings " + args.settings if args.settings else ""}`; '
             f'{platform.machine()}, {os.cpu_count()} cores, {time.perf_counter() - t_all:.0f} s in all. '
             'Newton: iterations per step; halved: steps of dt whose Newton did not converge, retried as half '
             'steps (never accepted); laid strain: the deployed arc length over its material length, minus 1.', '',
             '| dt s | e_mean cm | sigma cm | steps | Newton per step | max | halved | smallest step s | laid strain % '
             '| CPU s | note |', '|---|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        lines.append(f'| {r[0]:g} | {r[1]:.4f} | {r[2]:.4f} | {r[3]} | {r[4]:.2f} | {r[5]} | {r[6]} | {r[7]:g} | '
                     f'{r[8]:.2f} | {r[9]:.0f} | {r[10]} |')
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


if __name__ == '__main__':
    main()
