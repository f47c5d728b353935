"""Where a curved start's deployed error comes from beyond the plan's own (issue #10, letter C): the plan against the
pattern, the deployment against the plan, and controlled simulator changes, for the closest planned curve with its
start point fixed at the pattern's first point and free (``PlannerSettings.free_start_point``).

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/curved_start_decomposition.py \
        [--patterns letterC] [--rod 3] [--friction 0.5] [--commit-results]

Per pattern and start point: e_plan, Eq. 17 e_mean of the curve the grasps ask for (``asked_xy``) against the
processed pattern; e_dep, of the deployed curve against the pattern points (the deployment table's number);
e_dep_vs_plan, of the deployed curve against ``asked_xy`` (directed: what the rod did not lay of what it was asked);
e_rigid, e_dep after the best rigid motion of the deployed curve (Kabsch on the 50 points: the error a turn and shift
of the whole shape would remove); the free end's drift from where the plan puts it down; the turn of the first 3 cm
against the plan's; and the mean of |deployed - asked| over the first 20 cm and over the rest. Simulator variants, the
plan unchanged: ``base`` (the table's set-up), ``mu1`` (table friction 1.0 under a plan made for 0.5: what the
friction-limited laying costs), ``clamp3`` (the first 3 nodes held on the asked curve: a start that carries a
moment, ``SimulationSettings.clamp_start_xy``). Below the table: the curvature kappa_bar along the first 20 cm, asked
(``asked_xy``) and laid (the deployed curve's, from its points 5 mm apart), beside the planner's friction bound.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402
from deployment_table import RODS, all_patterns  # noqa: E402

from rod_deploy.deployment.metrics import N_POINTS, eq17_error, resample  # noqa: E402
from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment  # noqa: E402
from rod_deploy.planning.rod_description import rod_description_from_dict  # noqa: E402
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory  # noqa: E402


def rigid_error_cm(pattern_xy, deployed_xy):
    """Eq. 17 e_mean [cm] (directed) after the best rotation + translation of the deployed points."""
    a = resample(pattern_xy)
    b = resample(deployed_xy, length=float(np.sum(np.linalg.norm(np.diff(pattern_xy, axis=0), axis=1))))
    ca, cb = a.mean(0), b.mean(0)
    u, _, vt = np.linalg.svd((b - cb).T @ (a - ca))
    r = u @ vt
    if np.linalg.det(r) < 0:
        u[:, -1] *= -1
        r = u @ vt
    return 100 * float(np.linalg.norm((b - cb) @ r + ca - a, axis=1).mean())


def heading_deg(xy, length_m=0.03):
    s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    j = int(np.searchsorted(s, length_m))
    d = xy[j] - xy[0]
    return np.degrees(np.arctan2(d[1], d[0]))


def stretch_errors_cm(asked_xy, deployed_xy, split_m=0.2):
    """Mean |deployed - asked| at the 50 Eq. 17 points over s < split_m and s >= split_m [cm]."""
    length = float(np.sum(np.linalg.norm(np.diff(asked_xy, axis=0), axis=1)))
    a, b = resample(asked_xy), resample(deployed_xy, length=length)
    d = 100 * np.linalg.norm(a - b, axis=1)
    s = np.linspace(0, length, N_POINTS)
    return float(d[s < split_m].mean()), float(d[s >= split_m].mean())


def curvature_profile(asked_xy, deployed_xy, lgb_m, friction, until_m=0.2, step_m=0.005):
    """[(s [m], asked kappa_bar, laid kappa_bar, the bound mu (s / L_gb)^2 / 8)] every 1 cm up to ``until_m``: the
    turning of 5 mm chords over their spacing (released sign dropped: the C turns one way)."""
    length = float(np.sum(np.linalg.norm(np.diff(asked_xy, axis=0), axis=1)))
    n = int(length / step_m) + 1

    def kappa_bar(xy):
        d = np.diff(resample(xy, n, length=length), axis=0)
        return np.diff(np.unwrap(np.arctan2(d[:, 1], d[:, 0]))) / step_m * lgb_m
    ka, kl = kappa_bar(asked_xy), kappa_bar(deployed_xy)
    s = (np.arange(len(ka)) + 1) * step_m
    return [(s[i], ka[i], kl[i], friction * (s[i] / lgb_m) ** 2 / 8) for i in range(0, len(s), 2) if s[i] <= until_m]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--patterns', default='letterC')
    ap.add_argument('--rod', type=int, default=3)
    ap.add_argument('--friction', type=float, default=0.5)
    ap.add_argument('--variants', default='base,mu1,clamp3')
    ap.add_argument('--out-name', default='curved_start_decomposition.md')
    add_results_argument(ap)
    args = ap.parse_args()
    out = results_path(args, args.out_name)
    rod = rod_description_from_dict({**RODS[args.rod], 'friction': args.friction})
    base_sim = SimulationSettings(friction=args.friction)
    rows, t_all = [], time.perf_counter()
    for name, P in all_patterns(args.patterns).items():
        for free in (False, True):
            plan = plan_trajectory(P, rod, PlannerSettings(friction=args.friction, free_start_point=free))
            asked = plan.asked_xy
            e_plan = eq17_error(plan.drawn_pattern.xy, asked, directed=True)['e_mean_cm']
            for variant in args.variants.split(','):
                sim = base_sim
                if variant == 'mu1':
                    sim = replace(base_sim, friction=1.0)
                elif variant == 'clamp3':
                    dl = rod.length_m / max(int(round(rod.length_m / base_sim.edge_length_m)), 4)
                    sim = replace(base_sim, clamp_start_xy=tuple(map(tuple, resample(asked, 3, length=2 * dl))))
                elif variant != 'base':
                    raise SystemExit(f'unknown variant {variant}')
                cpu = time.process_time()
                res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod, sim)
                dep = res.deployed_xy
                e_dep = eq17_error(P, dep)['e_mean_cm']
                e_vs_plan = eq17_error(asked, dep, directed=True)['e_mean_cm']
                first, rest = stretch_errors_cm(asked, dep)
                row = dict(pattern=name, start='free' if free else 'fixed', variant=variant, e_plan=e_plan,
                           e_dep=e_dep, e_vs_plan=e_vs_plan, e_rigid=rigid_error_cm(P, dep),
                           drift_mm=1000 * float(np.linalg.norm(dep[0] - asked[0])),
                           turn_deg=float(((heading_deg(dep) - heading_deg(asked)) + 180) % 360 - 180),
                           first=first, rest=rest, moved_mm=1000 * float(np.linalg.norm(asked[0] - P[0])),
                           cpu=time.process_time() - cpu)
                row['profile'] = curvature_profile(asked, dep, rod.gravito_bending_length_m, sim.friction)
                rows.append(row)
                print(row, flush=True)
                write(out, rows, args, t_all)
    print(f'results: {out}')


def write(out, rows, args, t_all):
    lines = [f'# Curved start: plan vs deployment, `python benchmarks/curved_start_decomposition.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{os.getloadavg()[0]:.1f} at writing); {time.perf_counter() - t_all:.0f} s. Rod #{args.rod}, planned '
             f'for friction {args.friction:g} (nn, closest planned curve), our DER with the table\'s settings; '
             'Eq. 17 e_mean in cm (N = 50). Columns: see the script\'s docstring ("start moved": the planned '
             'free end from the pattern\'s first point).', '',
             '| pattern | start point | sim | e_plan | e_dep | e_dep_vs_plan | e_rigid | free end drift mm | '
             'first 3 cm turn deg | deployed vs plan, s < 20 cm | s >= 20 cm | start moved mm |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        lines.append(f'| {r["pattern"]} | {r["start"]} | {r["variant"]} | {r["e_plan"]:.3f} | {r["e_dep"]:.3f} | '
                     f'{r["e_vs_plan"]:.3f} | {r["e_rigid"]:.3f} | {r["drift_mm"]:.1f} | {r["turn_deg"]:.1f} | '
                     f'{r["first"]:.3f} | {r["rest"]:.3f} | {r["moved_mm"]:.1f} |')
    for r in rows:
        lines += ['', f'Curvature along the first 20 cm, {r["pattern"]}, {r["start"]} start point, sim {r["variant"]}: '
                  's [cm], asked kappa_bar, laid kappa_bar, the planner\'s bound mu (s / L_gb)^2 / 8', '',
                  '| s cm | ' + ' | '.join(f'{100 * p[0]:.1f}' for p in r['profile']) + ' |',
                  '|---|' + '---|' * len(r['profile']),
                  '| asked | ' + ' | '.join(f'{abs(p[1]):.3f}' for p in r['profile']) + ' |',
                  '| laid | ' + ' | '.join(f'{abs(p[2]):.3f}' for p in r['profile']) + ' |',
                  '| bound | ' + ' | '.join(f'{p[3]:.3f}' for p in r['profile']) + ' |']
    out.write_text('\n'.join(lines) + '\n')


if __name__ == '__main__':
    main()
