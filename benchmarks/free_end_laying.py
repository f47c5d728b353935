"""How the rod lays the curvature asked near its free end, where friction barely holds it (issue #10, the letter C's
remaining error): per pattern, the asked curvature (the curve the grasps ask for, ``plan.asked_xy``) and the laid one
(the deployed curve in our DER) along the first ``--until`` metres, beside the planner's friction bound
mu (s / L_gb)^2 / 8, saved for analysis (a measurement: nothing here changes the planner).

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/free_end_laying.py [--rods 3,2] \
        [--patterns letterC,letterG,digit6,wave_tight,spiral,circle,letterS,sine] [--friction 0.5] [--commit-results]

Curvature: the turning of 5 mm chords over their spacing (signed, kappa_bar = kappa L_gb), the deployed curve
resampled on the asked curve's length. Writes ``free_end_laying.npz`` (per case: s, asked, laid, bound) and a
markdown summary: per case the laid - asked excess binned by the friction use u = |asked| / bound, and the shift and
Gaussian smoothing of the asked curvature that come nearest the laid one over the first 25 cm (a grid: shifts -30..30
mm by 2, sigma 0-18 mm). ``--from-npz FILE`` writes the summary from saved profiles without simulating.
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
from deployment_table import RODS, all_patterns  # noqa: E402

from rod_deploy.deployment.metrics import eq17_error, resample  # noqa: E402
from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment  # noqa: E402
from rod_deploy.planning.rod_description import rod_description_from_dict  # noqa: E402
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory  # noqa: E402

STEP_M = 0.005


def signed_kappa_bar(xy, length_m, lgb_m):
    """(s (k,), kappa_bar (k,)) of ``xy`` resampled to 5 mm chords over ``length_m``."""
    n = int(length_m / STEP_M) + 1
    d = np.diff(resample(xy, n, length=length_m), axis=0)
    k = np.diff(np.unwrap(np.arctan2(d[:, 1], d[:, 0]))) / STEP_M * lgb_m
    return (np.arange(len(k)) + 1) * STEP_M, k


def nearest_filter(s, asked, laid, until_m=0.25):
    """(rms |laid - asked|, rms after, shift [m], sigma [m]) of laid(s) ~ asked(s + shift) smoothed by a Gaussian."""
    from scipy.ndimage import gaussian_filter1d
    m = s < until_m
    base = float(np.sqrt(np.mean((asked[m] - laid[m]) ** 2)))
    best = (base, 0.0, 0.0)
    for shift_mm in range(-30, 31, 2):
        for sigma_mm in (0, 2, 4, 6, 8, 10, 14, 18):
            a = np.interp(s + shift_mm / 1000, s, asked)
            if sigma_mm:
                a = gaussian_filter1d(a, sigma_mm / (1000 * STEP_M), mode='nearest')
            err = float(np.sqrt(np.mean((a[m] - laid[m]) ** 2)))
            if err < best[0] - 1e-12:
                best = (err, shift_mm / 1000, sigma_mm / 1000)
    return base, best[0], best[1], best[2]


def summary_row(key, prof, e_cm):
    s, ka, kl, bound = prof.T
    u = np.abs(ka) / np.maximum(bound, 1e-12)
    excess = np.sign(ka) * (kl - ka)                 # > 0: the rod laid more curvature than asked
    cells = []
    for lo, hi in [(0, 0.5), (0.5, 0.9), (0.9, 1.1), (1.1, np.inf)]:
        m = (u >= lo) & (u < hi) & (np.abs(ka) > 0.02)
        cells.append(f'{excess[m].mean():+.3f} ({m.sum()})' if m.any() else '-')
    base, after, shift, sigma = nearest_filter(s, ka, kl)
    rod, name = key.split('_', 1)
    return (f'| #{rod[3:]} | {name} | {e_cm} | ' + ' | '.join(cells) +
            f' | {base:.3f} -> {after:.3f} | {1000 * shift:+.0f} | {1000 * sigma:.0f} |')


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rods', default='3,2')
    ap.add_argument('--patterns', default='letterC,letterG,digit6,wave_tight,spiral,circle,letterS,sine')
    ap.add_argument('--friction', type=float, default=0.5)
    ap.add_argument('--until', type=float, default=0.3, help='arc length from the free end analysed [m]')
    ap.add_argument('--out-name', default='free_end_laying')
    ap.add_argument('--from-npz', help='write the summary from these saved profiles (no simulation)')
    add_results_argument(ap)
    args = ap.parse_args()
    t_all = time.perf_counter()
    saved, e_cm = {}, {}
    if args.from_npz:
        saved = dict(np.load(args.from_npz))
        e_cm = {k: '-' for k in saved}
    for rod_id in ([] if args.from_npz else (int(r) for r in args.rods.split(','))):
        rod = rod_description_from_dict(RODS[rod_id])
        lgb = rod.gravito_bending_length_m
        for name, P in all_patterns(args.patterns).items():
            plan = plan_trajectory(P, rod, PlannerSettings(friction=args.friction))
            res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod,
                                      SimulationSettings(friction=args.friction))
            length = float(np.sum(np.linalg.norm(np.diff(plan.asked_xy, axis=0), axis=1)))
            s, ka = signed_kappa_bar(plan.asked_xy, length, lgb)
            _, kl = signed_kappa_bar(res.deployed_xy, length, lgb)
            keep = s <= args.until
            key = f'rod{rod_id}_{name}'
            saved[key] = np.column_stack([s[keep], ka[keep], kl[keep], args.friction * (s[keep] / lgb) ** 2 / 8])
            e_cm[key] = f'{eq17_error(P, res.deployed_xy)["e_mean_cm"]:.3f}'
            print(summary_row(key, saved[key], e_cm[key]), flush=True)
            np.savez(results_path(args, args.out_name + '.npz'), **saved)
    lines = [summary_row(k, v, e_cm[k]) for k, v in saved.items()]
    head = ['# Laying near the free end, `python benchmarks/free_end_laying.py`', '',
            f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
            f'{os.getloadavg()[0]:.1f} at writing); {time.perf_counter() - t_all:.0f} s. Planner defaults at friction '
            f'{args.friction:g}, our DER at the same friction. Per case: e_mean [cm] (-: summary from saved profiles; '
            'the plans are the default planner\'s, e_mean in deployment_table_r7_*.md), and the mean excess of the '
            'laid over the asked curvature (kappa_bar, in the asked bend\'s sense; nodes with |asked| > 0.02 in the '
            f'first {100 * args.until:.0f} cm) binned by the friction use u = |asked| / (mu (s / L_gb)^2 / 8); in '
            'brackets '
            'the nodes (5 mm); rms: of laid - asked over the first 25 cm, then after the nearest shift and Gaussian '
            'smoothing of the asked curvature (laid(s) ~ asked(s + shift) smoothed by sigma).', '',
            '| rod | pattern | e_mean cm | u < 0.5 | 0.5-0.9 | 0.9-1.1 | > 1.1 | rms laid - asked | shift mm | '
            'sigma mm |',
            '|---|---|---|---|---|---|---|---|---|---|']
    results_path(args, args.out_name + '.md').write_text('\n'.join(head + lines) + '\n')
    print(f'results: {results_path(args, args.out_name + ".md")}')


if __name__ == '__main__':
    main()
