"""The floor of the friction-limited start (issue #10): the smallest Eq. 17 e_mean any curve can have against a
pattern when its curvature obeys the friction bound near the moment-free end.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/start_floor.py [--patterns letterC] \
        [--rods 1,2,3] [--frictions 0.2,0.5,1.0] [--commit-results]

For each pattern (the processed pattern the planner plans on, ``process_pattern`` with the planner's defaults), rod and
table friction mu, the curve of the pattern's length whose curvature kappa(s) (piecewise linear on the pattern's 5 mm
nodes, s from the free end) minimises Eq. 17's e_mean (mean distance at N = 50 points equally spaced by arc length,
directed: the free end at the pattern's first point's end), under

* ``pure-moment``: |kappa(s)| <= mu s^2 / (8 L_gb^3), the planner's bound (``friction_curvature_limit``, share 1);
* ``physical``: |kappa(s)| <= mu C(s) / (2 L_gb^3), the capacity with the sideways force M / x_g of the optimal grasp
  (``friction_moment_capacity_m2``, lever x_g = 2.5 L_gb): lower than the pure-moment bound;
* ``static``: |kappa(s)| <= mu s^2 / (4 L_gb^3), which every rod lying at rest on the table obeys whatever put it
  there: the moment EI kappa(s) at s must come from friction on [0, s] (the free end carries none), at most mu w per
  length at a lever |r(x) - r(s)| <= s - x, so |EI kappa(s)| <= mu w s^2 / 2, with EI = 2 w L_gb^3 (the contract's
  L_gb). Twice the pure-moment bound (all of [0, s] slipping the same way). A floor under this bound is a floor for
  any planner with the free end at the pattern's first point (as far as SLSQP finds the minimum, see below);
* ``pure-moment + rate``: the planner's bound and its curvature rate limit (``default_max_rate``: 0.35 sqrt(mu / 0.5)
  per L_gb), the constraints of the planner's closest curve (``closest_rate_limited_curve``);

each with the free end fixed at the pattern's first point (heading free) and with a free start point and heading.
Solved by SLSQP on the smoothed objective sum sqrt(d^2 + (0.01 mm)^2) with the bounds and rate limits as
constraints, started from the pattern's curvature clipped to the bound; the table gives Eq. 17
(``metrics.eq17_error``, directed) of the solution against the processed pattern and, in brackets, against the
pattern points as given. A local optimum (the problem is not convex): an upper bound on the true floor, tight
when restarts from other starts agree (``--restarts``).
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402
from deployment_table import RODS, all_patterns  # noqa: E402

from rod_deploy.deployment.metrics import N_POINTS, eq17_error, resample  # noqa: E402
from rod_deploy.planning.achievable_start import (_cumtrapz, friction_curvature_limit,  # noqa: E402
                                                  friction_moment_capacity_m2, integrate_curvature)
from rod_deploy.planning.curvature_rate import default_max_rate  # noqa: E402
from rod_deploy.planning.trajectory import PlannerSettings, process_pattern  # noqa: E402

LEVER_BAR = 2.5
EPS_M = 1e-5


def closest_bounded_curve(pattern, kappa_max, free_point, rate_bar=None, lgb=None, kappa_init=None):
    """(xy (m, 2), kappa (m,)) of the curve on the pattern's nodes nearest it in Eq. 17's e_mean with |kappa| <=
    kappa_max (m,) [1/m] (and |d kappa_bar / d(s / L_gb)| <= rate_bar when given); free heading, and free start
    point when ``free_point``."""
    s, target = pattern.s, pattern.xy
    n = len(s)
    ds = np.diff(s)
    u = np.linspace(0.0, s[-1], N_POINTS)
    j = np.clip(np.searchsorted(s, u, side='right') - 1, 0, n - 2)
    a = (u - s[j]) / ds[j]
    M = np.zeros((N_POINTS, n))
    M[np.arange(N_POINTS), j] = 1 - a
    M[np.arange(N_POINTS), j + 1] += a
    tu = M @ target
    dtheta = np.column_stack([np.ones(n), _cumtrapz(np.eye(n), ds)])       # d theta / d(theta0, kappa)
    theta_p = np.arctan2(pattern.tangent[0, 1], pattern.tangent[0, 0])

    def unpack(x):
        origin = target[0] + (x[-2:] if free_point else 0.0)
        return x[0], x[1:1 + n], origin

    def f_and_grad(x):
        th0, kappa, origin = unpack(x)
        xy, theta = integrate_curvature(s, th0, kappa, origin)
        e = M @ xy - tu
        d = np.sqrt((e ** 2).sum(axis=1) + EPS_M ** 2)
        g_xy = M.T @ (e / d[:, None]) / N_POINTS                      # (n, 2)
        dx = _cumtrapz(-np.sin(theta)[:, None] * dtheta, ds)
        dy = _cumtrapz(np.cos(theta)[:, None] * dtheta, ds)
        g = dx.T @ g_xy[:, 0] + dy.T @ g_xy[:, 1]
        if free_point:
            g = np.concatenate([g, g_xy.sum(axis=0)])
        return d.mean() / 1e-3, g / 1e-3                              # in mm: well scaled for SLSQP

    k0 = np.clip(pattern.kappa if kappa_init is None else kappa_init, -kappa_max, kappa_max)
    x0 = np.concatenate([[theta_p], k0, np.zeros(2) if free_point else []])
    bounds = [(None, None)] + [(-k, k) for k in kappa_max] + ([(None, None)] * 2 if free_point else [])
    cons = []
    if rate_bar is not None:
        D = np.zeros((n - 1, len(x0)))
        D[np.arange(n - 1), 1 + np.arange(n - 1)] = -1.0
        D[np.arange(n - 1), 2 + np.arange(n - 1)] = 1.0
        D *= lgb ** 2 / ds[:, None]                                   # d kappa_bar / d(s / L_gb)
        cons = [{'type': 'ineq', 'fun': lambda x: rate_bar - D @ x, 'jac': lambda x: -D},
                {'type': 'ineq', 'fun': lambda x: rate_bar + D @ x, 'jac': lambda x: D}]
        x0[1:1 + n] = np.clip(_rate_project(k0, ds, rate_bar / lgb ** 2), -kappa_max, kappa_max)
    sol = minimize(f_and_grad, x0, jac=True, bounds=bounds, constraints=cons, method='SLSQP',
                   options={'maxiter': 2000, 'ftol': 1e-12})
    th0, kappa, origin = unpack(sol.x)
    kappa = np.clip(kappa, -kappa_max, kappa_max)
    return integrate_curvature(s, th0, kappa, origin)[0], kappa


def starts(kappa, kappa_max, n):
    """n initial curvature profiles for SLSQP: the pattern's, then straight, half the pattern's, the bound with the
    pattern's sign, and random mixes (seeded)."""
    rng = np.random.default_rng(0)
    fixed = [kappa, np.zeros_like(kappa), 0.5 * kappa, np.sign(kappa) * kappa_max]
    for i in range(n):
        yield fixed[i] if i < len(fixed) else rng.uniform(0.0, 1.0, len(kappa)) * kappa


def _rate_project(k, ds, rate):
    from rod_deploy.planning.curvature_rate import limit_curvature_rate
    return limit_curvature_rate(k, float(np.mean(ds)), rate)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--patterns', default='letterC')
    ap.add_argument('--rods', default='1,2,3')
    ap.add_argument('--frictions', default='0.2,0.5,1.0')
    ap.add_argument('--bounds', default='physical,pure-moment,pure-moment+rate')
    ap.add_argument('--out-name', default='start_floor.md')
    ap.add_argument('--restarts', type=int, default=1, help='SLSQP starts per curve (the best kept; a difference '
                    'over 1e-4 cm between starts is printed)')
    add_results_argument(ap)
    args = ap.parse_args()
    out = results_path(args, args.out_name)
    pats = all_patterns(args.patterns)
    ps = PlannerSettings()
    rows, t_all = [], time.perf_counter()
    for name, P in pats.items():
        pattern = process_pattern(P, ps.step_m, ps.smoothing_m, ps.end_weight)
        for rod_id in (int(r) for r in args.rods.split(',')):
            lgb = RODS[rod_id]['L_gb']
            for mu in (float(m) for m in args.frictions.split(',')):
                for bound in args.bounds.split(','):
                    if bound == 'physical':
                        kmax = mu * friction_moment_capacity_m2(pattern.s, LEVER_BAR * lgb) / (2 * lgb ** 3)
                    elif bound == 'static':
                        kmax = friction_curvature_limit(pattern.s, lgb, mu, share=2.0)
                    else:
                        kmax = friction_curvature_limit(pattern.s, lgb, mu)
                    if bound != 'static':             # the network's range: a planner's limit, not the rod's
                        kmax = np.minimum(kmax, 0.9 * ps.max_abs_kappa_bar / lgb)
                    rate = default_max_rate(mu) if bound.endswith('+rate') else None
                    res, spread = [], []
                    for free in (False, True):
                        best = None
                        for init in starts(pattern.kappa, kmax, args.restarts):
                            xy, _ = closest_bounded_curve(pattern, kmax, free, rate, lgb, kappa_init=init)
                            e = eq17_error(pattern.xy, xy, directed=True)['e_mean_cm']
                            e_raw = eq17_error(P, xy, directed=True)['e_mean_cm']
                            shift = 100 * np.linalg.norm(xy[0] - pattern.xy[0])
                            if best is not None and abs(e - best[0]) > 1e-4:
                                print(f'  start {len(spread)}: {e:.4f} against {best[0]:.4f} cm', flush=True)
                            spread.append(e)
                            if best is None or e < best[0]:
                                best = (e, e_raw, shift)
                        res.append(best)
                    rows.append((name, rod_id, mu, bound, res))
                    print(name, rod_id, mu, bound, ' '.join(f'{r[0]:.3f} ({r[1]:.3f}) shift {r[2]:.2f}' for r in res),
                          flush=True)
                    write(out, rows, t_all)
    write(out, rows, t_all)
    print(f'results: {out}')


def write(out, rows, t_all):
    lines = ['# Floor of the friction-limited start, `python benchmarks/start_floor.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores (load average {os.getloadavg()[0]:.1f}); '
             f'{time.perf_counter() - t_all:.0f} s. The smallest Eq. 17 e_mean [cm] (N = 50, directed) of a curve of '
             'the pattern\'s length whose curvature obeys the bound (see the script\'s docstring), against the '
             'processed pattern (in brackets: against the pattern points as given); "start moved": how far the '
             'best curve\'s free end lies from the pattern\'s first point [cm].', '',
             '| pattern | rod | mu | bound | fixed start point: e_mean cm | free start point: e_mean cm | '
             'start moved cm |', '|---|---|---|---|---|---|---|']
    for name, rod_id, mu, bound, res in rows:
        lines.append(f'| {name} | #{rod_id} | {mu:g} | {bound} | {res[0][0]:.3f} ({res[0][1]:.3f}) | '
                     f'{res[1][0]:.3f} ({res[1][1]:.3f}) | {res[1][2]:.2f} |')
    out.write_text('\n'.join(lines) + '\n')


if __name__ == '__main__':
    main()
