"""How much a deployment's e_mean depends on a microscopic imperfection of the hanging rod (issue #10): the same
trajectory simulated in our DER with the rod perfect (imperfection 0) and with 1 um imperfections of several seeds
(``SimulationSettings.imperfection_m`` / ``imperfection_seed``): the spread over seeds is the simulator's sensitivity
to perturbations far below anything measurable, a floor under which two planners' e_mean cannot be told apart.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/imperfection_sensitivity.py \
        [--rods 3] [--friction medium] [--methods nn,published] [--patterns line,...] [--seeds 5] [--commit-results]
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
from deployment_table import REF, RODS, all_patterns, published_trajectory  # noqa: E402

from rod_deploy.deployment.metrics import eq17_error  # noqa: E402
from rod_deploy.deployment.simulate import FRICTION_LEVELS, SimulationSettings, simulate_deployment  # noqa: E402
from rod_deploy.planning.rod_description import rod_description_from_dict  # noqa: E402
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory  # noqa: E402

PAPER = 'line,circle,sine,letterU,letterC,letterL,letterA'


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rods', default='3')
    ap.add_argument('--friction', default='medium')
    ap.add_argument('--methods', default='nn,published')
    ap.add_argument('--patterns', default=PAPER)
    ap.add_argument('--seeds', type=int, default=5, help='seeds 1..N of the 1 um imperfection')
    ap.add_argument('--out-name', default='imperfection_sensitivity.md')
    add_results_argument(ap)
    args = ap.parse_args()
    out = results_path(args, args.out_name)
    rows, t_all = [], time.perf_counter()
    mu = FRICTION_LEVELS[args.friction]
    for rod_id in (int(r) for r in args.rods.split(',')):
        rod = rod_description_from_dict(RODS[rod_id])
        for name, P in all_patterns(args.patterns).items():
            for method in args.methods.split(','):
                start = None
                if method == 'published':
                    if rod_id != 3 or not (REF / 'reference_outputs' / f'{name}_traj_NN.txt').exists():
                        continue
                    t, p, q = published_trajectory(name)
                    start = tuple(P[0])
                else:
                    plan = plan_trajectory(P, rod, PlannerSettings(method=method, friction=mu))
                    t, p, q = plan.t, plan.position, plan.quaternion
                e = []
                for amp, seed in [(0.0, 0)] + [(1e-6, k) for k in range(1, args.seeds + 1)]:
                    res = simulate_deployment(t, p, q, rod, SimulationSettings(
                        friction=mu, start_xy=start, imperfection_m=amp, imperfection_seed=seed))
                    e.append(eq17_error(P, res.deployed_xy)['e_mean_cm'])
                    print(rod_id, name, method, amp, seed, f'{e[-1]:.3f}', flush=True)
                rows.append((rod_id, name, method, e[0], np.array(e[1:])))
                write(out, rows, t_all, args)
    print(f'results: {out}')


def write(out, rows, t_all, args):
    lines = ['# Sensitivity of a deployment to a 1 um imperfection, `python benchmarks/imperfection_sensitivity.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; '
             f'{time.perf_counter() - t_all:.0f} s. Our DER (defaults of `rod-deploy simulate`), friction '
             f'{args.friction}; each trajectory simulated with the hanging rod perfect and with a 1 um imperfection '
             f'of seeds 1..{args.seeds} (the default seed, 20261126, is not among them). Eq. 17 e_mean in cm.', '',
             '| rod | pattern | planner | perfect rod | 1 um, seeds: min | median | max | spread (max - min) |',
             '|---|---|---|---|---|---|---|---|']
    for rod_id, name, method, e0, e in rows:
        lines.append(f'| #{rod_id} | {name} | {method} | {e0:.3f} | {e.min():.3f} | {np.median(e):.3f} | '
                     f'{e.max():.3f} | {e.max() - e.min():.3f} |')
    spreads = np.array([r[4].max() - r[4].min() for r in rows])
    lines += ['', f'Spread over seeds: median {np.median(spreads):.3f} cm, largest {spreads.max():.3f} cm over '
              f'{len(rows)} trajectories.']
    out.write_text('\n'.join(lines) + '\n')


if __name__ == '__main__':
    main()
