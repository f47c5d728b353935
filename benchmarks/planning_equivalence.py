"""Do two versions of the planner plan the same trajectories? A broad set of plans is recorded by one version
(``--save``) and compared by another (``--against``): gripper positions [m] and orientations [rad] of every pose, the
error message of a refused plan, and the closest planned curve's fit (its final cost |r|^2 and the Jacobians
it formed, read by wrapping ``curvature_rate.levenberg_marquardt``).

    python benchmarks/planning_equivalence.py --save out/benchmarks/plans_before.npz       # on the old version
    python benchmarks/planning_equivalence.py --against out/benchmarks/plans_before.npz [--commit-results]

Plans: the paper's 7 patterns (``../shared/reference/rod_deployment/patterns``) and our own shapes of
``deployment_table.py`` on rods #1-#3 of its RODS; the acceptance rehearsal's shapes (``acceptance_rehearsal.py``) on
its rods (#2, #3 and the cable, friction 0.5); the 200-node spiral of ``planning_speed.py``; each with the default
settings (planned curve 'closest', start 'achievable') and with planned curve 'spread'.
"""
from __future__ import annotations

import argparse
import os
import subprocess
from pathlib import Path

import numpy as np
import yaml

from results_dir import add_results_argument, results_path
from rod_deploy.planning import curvature_rate
from rod_deploy.planning.pattern_input import PatternError
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, PlanningError, plan_trajectory

ROOT = Path(__file__).resolve().parents[1]


def cases():
    """[(name, points (n, 2) [m], RodDescription, PlannerSettings)]."""
    import acceptance_rehearsal as ar
    import deployment_table as dt
    from planning_speed import spiral
    out = []
    patterns = dt.all_patterns()
    for rod_no, rod in dt.RODS.items():
        for name, pts in patterns.items():
            out.append((f'{name} rod#{rod_no}', pts, rod_description_from_dict(rod)))
    for name, (pts, _, _) in ar.shapes().items():
        for rod in ar.RODS:
            desc = rod_description_from_dict(yaml.safe_load(ar.rod_yaml(rod, 'L_gb')))
            out.append((f'rehearsal {name} {rod}', pts, desc))
    out.append(('planning_speed spiral', spiral(), rod_description_from_dict({'length': 1.2, 'radius': 0.002,
                                                                               'L_gb': 0.034})))
    return [(f'{name} {curve}', pts, rod, PlannerSettings(planned_curve=curve))
            for name, pts, rod in out for curve in ('closest', 'spread')]


def fit_cost(residuals, x, kw):
    """The closest curve's fit cost |r|^2 at x, its limits' penalty rows included (the cap and the rate limit,
    handed to the solver as limits |D x| <= c since this change; before it the cap was a bound on x and the rate's
    penalty rows were residuals)."""
    r = residuals(x)
    if kw.get('limits') is not None:
        D, c, w = kw['limits']
        r = np.concatenate([r, w * np.maximum(np.abs(D @ x) - c, 0.0)])
    return float(r @ r)


def record():
    """({case name: dict(position, rotvec, error, kappa_bar, planned_xy, fit_x, fit_cost, fit_jacobians)} of this
    checkout's planner, {case name: (residuals, normal_equations, keywords) of its closest curve's fit})."""
    solve = curvature_rate.levenberg_marquardt
    fits = []

    def counted(residuals, normal_equations, x0, **kw):
        calls = [0]

        def ne(x, r):
            calls[0] += 1
            return normal_equations(x, r)
        x = solve(residuals, ne, x0, **kw)
        fits.append((x, fit_cost(residuals, x, kw), calls[0], (residuals, normal_equations, kw)))
        return x

    curvature_rate.levenberg_marquardt = counted
    from scipy.spatial.transform import Rotation
    out, problems = {}, {}
    try:
        for name, pts, rod, settings in cases():
            fits.clear()
            try:
                plan = plan_trajectory(pts, rod, settings)
                out[name] = dict(position=plan.position, rotvec=Rotation.from_quat(plan.quaternion).as_rotvec(),
                                 kappa_bar=plan.inputs[:, 2], planned_xy=plan.pattern.xy, error='')
            except (PlanningError, PatternError) as e:
                out[name] = dict(position=np.zeros((0, 3)), rotvec=np.zeros((0, 3)), kappa_bar=np.zeros(0),
                                 planned_xy=np.zeros((0, 2)), error=str(e))
            if fits:
                out[name].update(fit_x=fits[0][0], fit_cost=fits[0][1], fit_jacobians=fits[0][2])
                problems[name] = fits[0][3]
            else:
                out[name].update(fit_x=np.zeros(0), fit_cost=np.nan, fit_jacobians=0)
    finally:
        curvature_rate.levenberg_marquardt = solve
    return out, problems


def save(path, rec):
    arrays = {}
    for name, d in rec.items():
        for key, v in d.items():
            arrays[f'{name}|{key}'] = np.asarray(v)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)


def load(path):
    rec = {}
    with np.load(path) as z:
        for k in z.files:
            name, key = k.split('|')
            v = z[k]
            rec.setdefault(name, {})[key] = str(v) if key == 'error' else v
    return rec


def rotation_difference(rotvec, plan):
    from scipy.spatial.transform import Rotation
    return float(np.max((Rotation.from_rotvec(rotvec).inv() * Rotation.from_quat(plan.quaternion)).magnitude()))


def tight_plan(name):
    """The case planned with the closest curve's fit run to ftol = xtol = 1e-15 (the minimum itself)."""
    solve = curvature_rate.levenberg_marquardt

    def tight(residuals, normal_equations, x0, **kw):
        return solve(residuals, normal_equations, x0, **dict(kw, ftol=1e-15, xtol=1e-15))
    _, pts, rod, settings = next(c for c in cases() if c[0] == name)
    curvature_rate.levenberg_marquardt = tight
    try:
        return plan_trajectory(pts, rod, settings)
    finally:
        curvature_rate.levenberg_marquardt = solve


def compare(before, after, problems, args):
    """Rows (case, poses, max position difference [m], max orientation difference [rad], fit cost before, after,
    relative change, Jacobians before, after, verdict). Verdicts: 'same' (within the tolerances, fit cost not higher
    by more than cost_rtol); 'same minimum' (the same cost within cost_rtol, and this plan no further from the plan
    of the minimum itself - the fit run to ftol 1e-15 - than the earlier one: the difference is the earlier fit's
    stopping tolerance on a flat minimum); 'lower minimum' (this fit's cost is lower, and the earlier fit's x, continued by this
    solver to tight tolerances, ends at this cost: it had stopped short of the minimum); 'sign of zero' (the same
    planned curve, the trajectories differing only where the planned kappa_bar, below 1e-9, changed sign: the grasp
    network's mirror at kappa_bar < 0); 'error message differs'; 'DIFFERENT'."""
    from scipy.spatial.transform import Rotation
    rows = []
    for name in before:
        b, a = before[name], after[name]
        if str(b['error']) != str(a['error']):
            rows.append((name, len(a['position']), np.inf, np.inf, np.nan, np.nan, np.nan, 0, 0,
                         'error message differs'))
            continue
        if len(b['position']) and len(b['position']) == len(a['position']):
            dp = float(np.abs(b['position'] - a['position']).max())
            dr = float(np.max((Rotation.from_rotvec(b['rotvec']).inv()
                               * Rotation.from_rotvec(a['rotvec'])).magnitude()))
        elif len(b['position']) == len(a['position']) == 0:
            dp = dr = 0.0
        else:
            dp = dr = np.inf
        cb, ca = float(b['fit_cost']), float(a['fit_cost'])
        # relative change; costs below 1e-20 (residuals of 1e-10 L_gb) are both zero to rounding
        rel = 0.0 if max(ca, cb) < 1e-20 or np.isnan(cb) and np.isnan(ca) else (ca - cb) / cb
        same_plan = dp <= args.tolerance_m and dr <= args.tolerance_rad
        verdict = 'DIFFERENT'
        if same_plan and not rel > args.cost_rtol:
            verdict = 'same'
        elif rel < -args.cost_rtol and name in problems:
            residuals, normal_equations, kw = problems[name]
            x = curvature_rate.levenberg_marquardt(residuals, normal_equations, b['fit_x'], **dict(
                kw, ftol=1e-15, xtol=1e-15))
            continued = fit_cost(residuals, x, kw)
            if abs(continued - ca) <= args.cost_rtol * ca:
                verdict = f'lower minimum (the earlier x continued: {continued:.12g})'
        if verdict == 'DIFFERENT' and len(b['kappa_bar']) and len(b['kappa_bar']) == len(a['kappa_bar']) \
                and np.abs(b['planned_xy'] - a['planned_xy']).max() <= 1e-9:
            kb, ka = b['kappa_bar'], a['kappa_bar']
            flipped = np.sign(kb) != np.sign(ka)
            if np.abs(kb - ka).max() <= 1e-9 and flipped.any() and np.abs(kb[flipped]).max() < 1e-9:
                verdict = f'sign of zero ({int(flipped.sum())} nodes, |kappa_bar| < {np.abs(kb[flipped]).max():.0e})'
        if verdict == 'DIFFERENT' and abs(rel) <= args.cost_rtol and len(a['position']) and name in problems:
            # the same cost: is the difference each fit's distance from the minimum within its stopping tolerance?
            tight = tight_plan(name)
            d = [(float(np.abs(p['position'] - tight.position).max()), rotation_difference(p['rotvec'], tight))
                 for p in (b, a)]
            if d[1][0] <= max(d[0][0], args.tolerance_m) and d[1][1] <= max(d[0][1], args.tolerance_rad):
                verdict = (f'same minimum (the plan of the minimum run to ftol 1e-15 is {d[0][0]:.0e} m, '
                           f'{d[0][1]:.0e} rad from the earlier one, {d[1][0]:.0e} m, {d[1][1]:.0e} rad from this)')
            else:
                verdict = (f'DIFFERENT (the plan of the minimum run to ftol 1e-15 is {d[0][0]:.0e} m, '
                           f'{d[0][1]:.0e} rad from the earlier one, {d[1][0]:.0e} m, {d[1][1]:.0e} rad from this)')
        rows.append((name, len(a['position']), dp, dr, cb, ca, rel, int(b['fit_jacobians']), int(a['fit_jacobians']),
                     verdict))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument('--save', help='record this checkout\'s plans into this .npz')
    g.add_argument('--against', help='compare this checkout\'s plans with the ones recorded in this .npz')
    ap.add_argument('--label', help='what --save records (default: this checkout\'s commit)')
    ap.add_argument('--tolerance-m', type=float, default=1e-6)
    ap.add_argument('--tolerance-rad', type=float, default=1e-6)
    ap.add_argument('--cost-rtol', type=float, default=1e-9)
    add_results_argument(ap)
    args = ap.parse_args()
    commit = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    if args.save:
        rec, _ = record()
        rec['_meta'] = {'commit': args.label or commit}
        save(args.save, rec)
        print(f'{len(rec) - 1} plans recorded into {args.save}')
        return
    before = load(args.against)
    meta = before.pop('_meta', {})
    after, problems = record()
    rows = compare(before, after, problems, args)
    planned = [r for r in rows if r[1]]
    fitted = [r for r in rows if np.isfinite(r[4])]
    worst_p = max(planned, key=lambda r: r[2])
    worst_r = max(planned, key=lambda r: r[3])
    verdicts = {}
    for r in rows:
        key = r[9].split(' (')[0]
        verdicts[key] = verdicts.get(key, 0) + 1
    ok = all(r[9] == 'same' or r[9].startswith(('same minimum', 'lower minimum', 'sign of zero')) for r in rows)
    rel = np.array([r[6] for r in fitted])
    jb, ja = np.array([r[7] for r in fitted]), np.array([r[8] for r in fitted])
    lines = ['# Planning equivalence (`python benchmarks/planning_equivalence.py`)', '',
             f'Plans of the checkout {commit} against those recorded by {meta.get("commit", "?")} '
             f'({os.path.basename(args.against)}): {len(rows)} cases, {len(planned)} planned, '
             f'{len(rows) - len(planned)} refused.', '',
             f'* verdicts: {", ".join(f"{k} {v}" for k, v in sorted(verdicts.items()))}; overall: '
             f'{"the same plans (or a lower fit cost)" if ok else "DIFFERENT"}',
             f'* largest gripper position difference: {worst_p[2]:.2e} m ({worst_p[0]}); tolerance '
             f'{args.tolerance_m:g} m',
             f'* largest gripper orientation difference: {worst_r[3]:.2e} rad ({worst_r[0]}); tolerance '
             f'{args.tolerance_rad:g} rad',
             f'* the closest curve\'s fit ({len(fitted)} fits): relative change of the final cost |r|^2 from '
             f'{rel.min():.2e} to {rel.max():.2e} (negative: lower); tolerance +{args.cost_rtol:g}',
             f'* Jacobians formed per fit: median {np.median(jb):.0f} -> {np.median(ja):.0f}, total '
             f'{jb.sum()} -> {ja.sum()}', '',
             '| case | poses | max d position m | max d orientation rad | fit cost before | after | relative | '
             'Jacobians before | after | verdict |', '|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        lines.append(f'| {r[0]} | {r[1]} | {r[2]:.1e} | {r[3]:.1e} | {r[4]:.12g} | {r[5]:.12g} | {r[6]:.1e} | '
                     f'{r[7]} | {r[8]} | {r[9]} |')
    out = results_path(args, 'planning_equivalence.md')
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines[:9]))
    raise SystemExit(0 if ok else 1)


if __name__ == '__main__':
    main()
