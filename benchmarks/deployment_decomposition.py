"""Where the simulated deployment error comes from: controlled runs, one change at a time from the baseline.

    python benchmarks/deployment_decomposition.py [--rod 3] [--patterns circle,sine,letterC,letterA]
                                                  [--variants all] [--tag NAME] [--commit-results]

Baseline: our network's plan (``nn``) as it was before this study (equal spline weights, tangent start), the
paper's rod (default #3), medium friction (0.5), our DER simulator with
its defaults (5 mm edges, dt 0.02 s, gripper at 0.01 m/s, the free end released after the lead-in). Variants, each
changing one thing: ``hold`` the free end pinned throughout (``hold_free_end='always'``); ``slow`` the gripper at
half speed (0.005 m/s); ``fine`` 2.5 mm edges; ``numeric`` the numeric planner instead of the network; ``mu1`` high
friction (1.0); planner changes: ``ends`` the spline's end weights (``PlannerSettings.end_weight``), ``start`` the
friction-limited start (``PlannerSettings.start='achievable'``), ``both``, ``both_half`` (both, counting on half
the friction: ``friction_share=0.5``).

Besides Eq. 17 each run reports the part of the error a rigid motion of the deployed curve removes (``e_rigid``:
e_mean after the best rotation + translation, Kabsch on the N = 50 resampled points), how far the free end moved
from the pattern's first point, and the angle between the first 3 cm of the deployed curve and of the pattern.
The deployed shapes are saved (npz) next to the table for plots.

``--truncate-m X`` (exploration on a loaded machine): only the first X m of each pattern, laid by a rod X + 0.2 m
long (the same L_gb and radius), about 4x cheaper than the full 0.9 m deployment.
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from dataclasses import replace

import numpy as np

from deployment_table import RODS, all_patterns
from results_dir import add_results_argument, results_path
from rod_deploy.deployment.metrics import eq17_error, resample
from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

#: the planner as it was (equal spline weights, tangent start): the README's 'after' table
BASE_PLAN = PlannerSettings(end_weight=1.0, start='tangent')
BASE_SIM = SimulationSettings(friction=0.5)
VARIANTS = {
    'base': (BASE_PLAN, BASE_SIM),
    'hold': (BASE_PLAN, replace(BASE_SIM, hold_free_end='always')),
    'slow': (BASE_PLAN, replace(BASE_SIM, max_gripper_speed_m_s=0.005)),
    'fine': (BASE_PLAN, replace(BASE_SIM, edge_length_m=0.0025)),
    'numeric': (replace(BASE_PLAN, method='numeric'), BASE_SIM),
    'mu1': (BASE_PLAN, replace(BASE_SIM, friction=1.0)),
    'ends': (replace(BASE_PLAN, end_weight=PlannerSettings().end_weight), BASE_SIM),
    'start': (replace(BASE_PLAN, start='achievable', friction_share=1.0), BASE_SIM),
    'both': (replace(BASE_PLAN, end_weight=PlannerSettings().end_weight, start='achievable', friction_share=1.0),
             BASE_SIM),
    'both_half': (replace(BASE_PLAN, end_weight=PlannerSettings().end_weight, start='achievable',
                          friction_share=0.5), BASE_SIM),
}


def rigid_residual_cm(pattern_xy, deployed_xy, n=50):
    """e_mean after the best rigid motion (rotation + translation) of the deployed curve onto the pattern [cm]."""
    lp = float(np.sum(np.linalg.norm(np.diff(pattern_xy, axis=0), axis=1)))
    a = resample(pattern_xy, n)
    b = resample(deployed_xy, n, length=lp)
    ca, cb = a.mean(0), b.mean(0)
    U, _, Vt = np.linalg.svd((b - cb).T @ (a - ca))
    D = np.diag([1.0, np.sign(np.linalg.det(U @ Vt))])
    R = (U @ D @ Vt).T
    b_fit = (b - cb) @ R.T + ca
    return 100 * float(np.mean(np.linalg.norm(a - b_fit, axis=1)))


def start_angle_deg(pattern_xy, deployed_xy, length_m=0.03):
    def heading(xy):
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
        k = int(np.searchsorted(s, length_m))
        d = xy[min(k, len(xy) - 1)] - xy[0]
        return np.arctan2(d[1], d[0])
    a = heading(deployed_xy) - heading(pattern_xy)
    return float(np.degrees((a + np.pi) % (2 * np.pi) - np.pi))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rod', type=int, default=3)
    ap.add_argument('--patterns', default='circle,sine,letterC,letterA')
    ap.add_argument('--variants', default='all', help=f'comma-separated from {",".join(VARIANTS)}, or all')
    ap.add_argument('--truncate-m', type=float, default=None, help='only the first X m of each pattern, rod X + 0.2 m')
    ap.add_argument('--tag', default='', help='suffix of the results file (parallel runs)')
    add_results_argument(ap)
    args = ap.parse_args()
    rod_dict = dict(RODS[args.rod])
    patterns = all_patterns(args.patterns)
    if args.truncate_m:
        rod_dict['length'] = args.truncate_m + 0.2
        for name, P in patterns.items():
            s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
            patterns[name] = P[s <= args.truncate_m]
    rod = rod_description_from_dict(rod_dict)
    variants = list(VARIANTS) if args.variants == 'all' else args.variants.split(',')
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        ap.error(f'unknown variant(s) {", ".join(unknown)} (one of {", ".join(VARIANTS)})')
    tag = f'_{args.tag}' if args.tag else ''
    out = results_path(args, f'deployment_decomposition{tag}.md')
    rows, shapes = [], {}
    t_all = time.perf_counter()
    for name, P in patterns.items():
        for v in variants:
            plan_s, sim_s = VARIANTS[v]
            t0 = time.perf_counter()
            plan = plan_trajectory(P, rod, plan_s)
            res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod, sim_s)
            e = eq17_error(P, res.deployed_xy, directed=True)
            row = dict(pattern=name, variant=v, e_mean=e['e_mean_cm'], sigma=e['sigma_cm'],
                       e_rigid=rigid_residual_cm(P, res.deployed_xy),
                       free_end_mm=1000 * float(np.linalg.norm(res.nodes[0, :2] - P[0])),
                       start_deg=start_angle_deg(P, res.deployed_xy), coverage=e['coverage'],
                       wall_s=time.perf_counter() - t0)
            rows.append(row)
            shapes[f'{name}/{v}'] = res.deployed_xy
            shapes[f'{name}/{v}/plan'] = plan.pattern.xy
            print(f"{name:10s} {v:8s} e_mean {row['e_mean']:.3f} cm  rigid-aligned {row['e_rigid']:.3f} cm  "
                  f"free end {row['free_end_mm']:.1f} mm  start {row['start_deg']:+.1f} deg  "
                  f"({row['wall_s']:.0f} s)", flush=True)
    np.savez_compressed(out.with_suffix('.npz'), **shapes)
    lines = [f'# Deployment error decomposition, `python benchmarks/deployment_decomposition.py '
             f'--rod {args.rod} --patterns {args.patterns} --variants {args.variants}'
             f'{f" --truncate-m {args.truncate_m}" if args.truncate_m else ""}`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores (shared, loaded); '
             f'{time.perf_counter() - t_all:.0f} s in all. Rod #{args.rod} ({rod.length_m:g} m long); '
             'baseline: nn plan, mu 0.5, 5 mm edges, '
             'dt 0.02 s, 0.01 m/s, free end released after the lead-in. e_rigid: e_mean after the best rigid '
             'motion of the deployed curve; free end: its final distance from the pattern\'s first point; start: '
             'heading of the first 3 cm, deployed minus pattern.', '',
             '| pattern | variant | e_mean cm | sigma cm | e_rigid cm | free end mm | start deg | coverage | wall s |',
             '|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        lines.append(f"| {r['pattern']} | {r['variant']} | {r['e_mean']:.3f} | {r['sigma']:.3f} | "
                     f"{r['e_rigid']:.3f} | {r['free_end_mm']:.1f} | {r['start_deg']:+.1f} | {r['coverage']:.2f} | "
                     f"{r['wall_s']:.0f} |")
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


if __name__ == '__main__':
    main()
