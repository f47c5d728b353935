"""Why the laid rod is dragged at bends (issue #10): the friction the touch-down point needs against what it has,
and the drag measured in our DER, node by node (``rod_deploy.planning.bend_drag``).

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/bend_drag_mechanism.py \
        [--patterns letterA,letterL,digit2,wave_tight] [--rod 3] [--friction medium] [--commit-results]

1. The contact forces of the optimal grasp at the touch-down point (the numeric solver, ``contact_force_table``)
   per |kappa_bar|, at ls_bar 5 and 20, against the table stored in ``bend_drag`` (CONTACT_FY, CONTACT_FZ).
2. For each pattern: the planner's plan WITHOUT the drag compensation (``drag_compensation=False``), replayed in our
   DER with the rod's nodes kept every 0.2 s (``replay_probe.run_der``). Per node i (arc length s_i from the free
   end): the drag, the node's motion on the table after its touch-down (first snapshot from which it stays within
   0.5 mm of the table) along the pattern's inward normal; beside it the friction demand D = F_y(kappa_bar) +
   d kappa_bar / d(s / L_gb) of the planned curvature, the capacity mu F_z and the predicted drag (``drag_offsets``
   with gain 1: the excess |D| - mu F_z, smoothed and tapered as the planner does). Per 4 cm stretch the largest
   values; per pattern the correlation of the predicted and measured drag and their least-squares slope; pooled,
   the slope at friction 0.5 is ``bend_drag.DRAG_GAIN``.
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

G = 9.81
DENSITY = 1180.0


def measured_drag(nodes, n, radius_m, inward, tol_m=5e-4):
    """(k,) the motion of the first n nodes on the table after their touch-down, along ``inward`` (k, 2)."""
    on = nodes[:, :n, 2] <= radius_m + tol_m
    stays = np.flip(np.cumprod(np.flip(on, axis=0), axis=0), axis=0).astype(bool)
    laid = stays.any(axis=0)
    first = np.argmax(stays, axis=0)
    moved = nodes[-1, :n, :2] - nodes[first, np.arange(n), :2]
    return np.where(laid, np.sum(moved * inward, axis=1), np.nan)


def main():
    from deployment_table import RODS, all_patterns
    from replay_probe import run_der
    from rod_deploy.deployment.simulate import FRICTION_LEVELS
    from rod_deploy.planning.bend_drag import (CONTACT_FY, CONTACT_FZ, CONTACT_KAPPA_BAR, DRAG_GAIN,
                                               contact_force_table, drag_offsets, friction_demand)
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--patterns', default='letterA,letterL,digit2,wave_tight')
    ap.add_argument('--rod', type=int, default=3)
    ap.add_argument('--friction', default='medium')
    ap.add_argument('--out-name', default='bend_drag_mechanism.md')
    add_results_argument(ap)
    args = ap.parse_args()
    t_all = time.perf_counter()
    rod = rod_description_from_dict(RODS[args.rod])
    mu = FRICTION_LEVELS[args.friction]
    Lgb, h = rod.gravito_bending_length_m, rod.radius_m
    w = DENSITY * G * np.pi * h ** 2
    unit = 2.0 * w * Lgb                                   # k_b / L_gb^2 = 2 w L_gb [N]
    lines = [f'# The drag at bends, `python benchmarks/bend_drag_mechanism.py` (rod #{args.rod}, friction {mu:g})', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{os.getloadavg()[0]:.1f} at the start). Units: forces in k_b / L_gb^2 = 2 w L_gb = '
             f'{1e3 * unit:.2f} mN for this rod (w = rho g pi h^2 = {1e3 * w:.1f} mN/m, rho {DENSITY:g} kg/m^3, '
             f'L_gb {100 * Lgb:.1f} cm).', '',
             '## 1. The optimal grasp at the touch-down point', '',
             'F_y: lateral force of the suspended part on the table side (towards the inside of the bend), F_z: the '
             'table\'s point reaction at the lift-off point, mu F_z the friction it can hold there; the numeric '
             'solver (`optimal_grasp`, inextensible, and ks_bar 500) against the stored table.', '',
             '| abs kappa_bar | F_y ls 20 | F_y ls 5, ks 500 | F_y stored | F_z ls 20 | F_z ls 5, ks 500 | F_z stored | '
             'mu F_z | F_y / (mu F_z) |', '|---|---|---|---|---|---|---|---|---|']
    kbs = CONTACT_KAPPA_BAR[::2]
    fy20, fz20 = contact_force_table(kbs, 20.0)
    from rod_deploy.planning.optimal_grasp import optimal_grasp
    f5 = [optimal_grasp(5.0, float(k), 500.0, check_stability=False).clamp_force for k in kbs]
    for k, a, b, c in zip(kbs, fy20, fz20, f5):
        i = int(np.argmin(abs(CONTACT_KAPPA_BAR - k)))
        lines.append(f'| {k:.2f} | {a:.4f} | {c[1]:.4f} | {CONTACT_FY[i]:.4f} | {b:.4f} | {c[2]:.4f} | '
                     f'{CONTACT_FZ[i]:.4f} | {mu * b:.3f} | {a / (mu * b):.2f} |')
    lines += ['', '## 2. Demand, capacity and the measured drag along the patterns', '',
              'Per 4 cm stretch of the pattern (arc length from the free end): the largest |kappa_bar| planned, the '
              'largest demand |D| = |F_y + d kappa_bar / d s_bar|, the smallest capacity mu F_z, the largest '
              'excess, the largest measured drag (inward motion after touch-down) and the predicted one '
              f'(gain {DRAG_GAIN:g} L_gb x the smoothed excess), mm.', '']
    X, Y, summary = [], [], []
    for name in args.patterns.split(','):
        P = all_patterns(name)[name]
        plan = plan_trajectory(P, rod, PlannerSettings(friction=mu, drag_compensation=False))
        g = plan.drawn_pattern
        kb = np.interp(g.s, plan.pattern.s, plan.inputs[:, 2])
        D, fz = friction_demand(g.s / Lgb, kb)
        excess = np.maximum(np.abs(D) - mu * fz, 0.0)
        left = np.column_stack([-g.tangent[:, 1], g.tangent[:, 0]])
        pred = np.sum(drag_offsets(g.s, g.tangent, kb, Lgb, mu, gains=(1.0, 0.0)) * left, axis=1)   # outward, per gain
        times, nodes, deployed, *_ = run_der((plan.t, plan.position, plan.quaternion, None), rod, mu, {}, 0.2)
        n = min(nodes.shape[1], len(g.s))
        # inward: the side the demand pulls to (sign of D: > 0 to the right, -left); the offsets' outward sign
        meas = measured_drag(nodes, n, h, -left[:n])      # motion to the right, as pred's outward-left sign
        ok = np.isfinite(meas)
        x, y = pred[:n][ok], meas[ok]
        slope, corr = float(x @ y / (x @ x)), float(np.corrcoef(x, y)[0, 1])
        X.append(x)
        Y.append(y)
        from rod_deploy.deployment.metrics import eq17_error
        e = eq17_error(P, deployed)['e_mean_cm']
        summary.append((name, e, slope, corr, float(np.max(np.abs(y))), float(np.max(excess))))
        lines += [f'### {name}: e_mean {e:.3f} cm (uncompensated plan); predicted vs measured drag: correlation '
                  f'{corr:.2f}, slope {slope:.3f} L_gb per unit excess', '',
                  '| s cm | max abs kappa_bar | max abs D | min mu F_z | max excess | max measured drag mm | '
                  'max predicted drag mm |', '|---|---|---|---|---|---|---|']
        for a in np.arange(0.0, g.s[n - 1], 0.04):
            k = (g.s[:n] >= a) & (g.s[:n] < a + 0.04)
            km = k & ok
            lines.append(f'| {100 * a:.0f}-{100 * (a + 0.04):.0f} | {np.abs(kb[:n][k]).max():.2f} | '
                         f'{np.abs(D[:n][k]).max():.3f} | {(mu * fz[:n][k]).min():.3f} | {excess[:n][k].max():.3f} | '
                         f'{1e3 * np.abs(meas[km]).max() if km.any() else float("nan"):.2f} | '
                         f'{1e3 * DRAG_GAIN * np.abs(pred[:n][k]).max():.2f} |')
        lines.append('')
        print(f'{name}: e_mean {e:.3f}, slope {slope:.3f}, corr {corr:.2f}', flush=True)
    X, Y = np.concatenate(X), np.concatenate(Y)
    pooled = float(X @ Y / (X @ X))
    lines += ['## Summary', '', '| pattern | e_mean cm | largest excess | largest drag mm | correlation | slope |',
              '|---|---|---|---|---|---|']
    for r in summary:
        lines.append(f'| {r[0]} | {r[1]:.3f} | {r[5]:.3f} | {1e3 * r[4]:.2f} | {r[3]:.2f} | {r[2]:.3f} |')
    lines += ['', f'Pooled over {len(X)} nodes: least-squares slope {pooled:.3f} L_gb per unit excess (correlation '
              f'{float(np.corrcoef(X, Y)[0, 1]):.2f}); the planner uses DRAG_GAIN = {DRAG_GAIN:g}. '
              f'{time.perf_counter() - t_all:.0f} s in all.']
    out = results_path(args, args.out_name)
    out.write_text('\n'.join(lines) + '\n')
    print(f'pooled slope {pooled:.3f}; results: {out}')


if __name__ == '__main__':
    main()
