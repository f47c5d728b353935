"""The friction regularisation velocity of our DER (issue #10): does a simulated deployment converge as it goes to
zero, what does a smaller one cost, and how far does a laid rod creep under a load Coulomb's law holds still?

    python benchmarks/friction_regularisation.py [--cases 3:letterU,3:letterA,1:circle]
        [--velocities 1e-4,3e-5,1e-5,3e-6,1e-6] [--dt 0.02] [--dt-check 1e-5] [--creep-only | --no-creep] [--commit-results]

(1) Deployments: each case ``ROD:PATTERN`` (rods of ``deployment_table.RODS``, medium friction 0.5) is planned once
    with the default planner (nn, friction-limited start) and simulated at every regularisation velocity, dt 0.02 s
    (and at dt 0.01 s for the ``--dt-check`` velocity). Reported: e_mean (Eq. 17), Newton iterations per step (mean,
    max), steps halved because Newton did not converge (never accepted), the smallest step, CPU seconds.
(2) Creep: a straight rod (rod #3's material, 0.2 m, 5 mm edges) at rest on the table, after 0.3 s of settling a
    uniform sideways body force of half the friction limit (a = 0.5 mu g) for 10 s, dt 0.02 s. Coulomb's answer is
    no motion at all. Friction is mu N v / sqrt(v^2 + v_f^2), so the steady creep speed at a load ratio r is
    v_f r / sqrt(1 - r^2) (0.577 v_f at r = 0.5, 5.77 v_f metres in 10 s); reported next to the measured mean
    displacement.
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import time

import numpy as np

from deployment_table import RODS, all_patterns
from results_dir import add_results_argument, results_path
from rod_deploy.deployment.metrics import eq17_error
from rod_deploy.deployment.simulate import FRICTION_LEVELS, SimulationSettings, material_parameters, \
    simulate_deployment
from rod_deploy.physics.der_simulator import DiscreteElasticRod
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

MU = FRICTION_LEVELS['medium']
G = 9.81


def creep(friction_velocity, ratio=0.5, t_load=10.0, dt=0.02, settle=0.3, length=0.2, edge=0.005):
    """Mean sideways displacement [m] of a straight rod #3 on the table after ``t_load`` s of a uniform sideways
    load ``ratio`` x the friction limit; also the Newton statistics and CPU seconds."""
    rod = rod_description_from_dict(RODS[3])
    params = material_parameters(rod, MU, 2.0, friction_velocity)
    n = int(round(length / edge))
    x = np.linspace(0.0, length, n + 1)
    nodes0 = np.column_stack([x, np.zeros_like(x), np.full_like(x, rod.radius_m)])
    model = DiscreteElasticRod(nodes0, params, d1_first=np.array([0.0, 0.0, 1.0]))
    extra = np.zeros(model.ndof)
    for i, m in enumerate(model.node_mass):
        extra[model.node_dof(i)] = m * np.array([0.0, ratio * MU * G, 0.0])
    t0 = time.process_time()
    its = []
    for _ in range(int(round(settle / dt))):
        its.append(model.step(dt))
    p_on = model.nodes.copy()
    model.gravity_force = model.gravity_force + extra
    for _ in range(int(round(t_load / dt))):
        its.append(model.step(dt))
    moved = float(np.mean(model.nodes[:, 1] - p_on[:, 1]))
    its = [i for i in its if isinstance(i, (int, np.integer))]
    return moved, (max(its) if its else -1), time.process_time() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--cases', default='3:letterU,3:letterA,1:circle')
    ap.add_argument('--velocities', default='1e-4,3e-5,1e-5,3e-6,1e-6')
    ap.add_argument('--dt', type=float, default=0.02, help='time step of the main runs [s]')
    ap.add_argument('--dt-check', type=float, default=None, help='also simulate at dt 0.01 s with this velocity')
    ap.add_argument('--creep-only', action='store_true')
    ap.add_argument('--no-creep', action='store_true')
    ap.add_argument('--out-name', default='friction_regularisation.md')
    add_results_argument(ap)
    args = ap.parse_args()
    vels = [float(v) for v in args.velocities.split(',')]
    out = results_path(args, args.out_name)
    t_all = time.perf_counter()
    lines = ['# The friction regularisation velocity: deployments and creep', '',
             f'`python benchmarks/friction_regularisation.py --cases {args.cases} --velocities {args.velocities}'
             f'{" --dt %g" % args.dt if args.dt != 0.02 else ""}{" --creep-only" if args.creep_only else ""}'
             f'{" --no-creep" if args.no_creep else ""}'
             f'{" --dt-check %g" % args.dt_check if args.dt_check else ""}`; {platform.machine()}, '
             f'{os.cpu_count()} cores (shared). Medium friction (0.5), default planner (nn, friction-limited start), '
             'edge 5 mm, gripper 0.01 m/s, damping 2/s.', '']
    if not args.creep_only:
        lines += ['## Deployments', '',
                  'Newton: iterations per step (mean, max); halved: steps of dt whose Newton did not converge, '
                  'retried as two half steps (never accepted); CPU: the simulation only.', '',
                  '| rod | pattern | v_f m/s | dt s | e_mean cm | sigma cm | steps | Newton mean | max | halved | '
                  'smallest step s | CPU s | note |', '|---|---|---|---|---|---|---|---|---|---|---|---|---|']
        for case in args.cases.split(','):
            rod_id, name = case.split(':')
            rod = rod_description_from_dict(RODS[int(rod_id)])
            P = all_patterns(name)[name]
            plan = plan_trajectory(P, rod, PlannerSettings(method='nn', friction=MU))
            runs = [(v, args.dt) for v in vels]
            if args.dt_check:
                runs.append((args.dt_check, 0.01))
            for v, dt in runs:
                t0 = time.process_time()
                try:
                    res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod,
                                              SimulationSettings(friction=MU, dt_s=dt, friction_velocity_m_s=v))
                    e = eq17_error(P, res.deployed_xy)
                    row = (e['e_mean_cm'], e['sigma_cm'], res.steps, res.newton_iterations / res.steps,
                           res.max_newton_iterations, res.halved_steps, res.smallest_step_s, '')
                except ValueError as exc:
                    row = (math.nan, math.nan, 0, math.nan, 0, 0, math.nan, str(exc)[:120])
                cpu = time.process_time() - t0
                line = (f'| #{rod_id} | {name} | {v:g} | {dt:g} | {row[0]:.4f} | {row[1]:.4f} | {row[2]} | '
                        f'{row[3]:.2f} | {row[4]} | {row[5]} | {row[6]:g} | {cpu:.0f} | {row[7]} |')
                print(line, flush=True)
                lines.append(line)
        lines.append('')
    if not args.no_creep:
        lines += ['## Creep of a straight rod under half the friction limit', '',
                  'Rod #3 material, 0.2 m straight on the table, sideways load 0.5 mu m g for 10 s after 0.3 s of '
                  'settling, dt 0.02 s. Coulomb: 0. Predicted by the regularised law: 0.5 / sqrt(0.75) v_f x 10 s.',
                  '', '| v_f m/s | creep in 10 s mm | predicted mm | max Newton | CPU s |', '|---|---|---|---|---|']
        for v in vels:
            moved, itmax, cpu = creep(v)
            line = (f'| {v:g} | {1e3 * moved:.4f} | {1e3 * 0.5 / math.sqrt(0.75) * v * 10:.4f} | {itmax} | '
                    f'{cpu:.1f} |')
            print(line, flush=True)
            lines.append(line)
    lines += ['', f'{time.perf_counter() - t_all:.0f} s wall in all.']
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


if __name__ == '__main__':
    main()
