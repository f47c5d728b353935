"""Issue #10: which start should the planner's default be? The friction-limited start (``--start achievable``, the
default) against Alg. 4's tangent start (``--start tangent``), measured with the current simulator (the rod at its
own rest length) on shapes the default was not chosen on.

    python benchmarks/start_comparison.py [--only NAME,...] [--commit-results] [--report-only]

Rod #3 of the paper (L_gb 0.034 m, radius 0.002 m, length 0.89 m), friction 0.5 (planner and simulator), the nn
method. Shapes, fixed before any run of this script:

* the paper's 7 patterns (``../shared/reference/rod_deployment/patterns``, read in place; the default start was
  chosen on them, with the stretched rest length);
* every shape of the acceptance rehearsal's generator (``acceptance_rehearsal.shapes()``, drawn for it by code and
  used to develop nothing), written to a points file and read back exactly as ``rod-deploy plan`` reads it, except
  ``letter_e_moved`` (a rigid copy of ``letter_e``, which the rehearsal found to score the same to 1e-4 cm: it would
  count the e twice). Shapes the planner refuses for rod #3 (cusps, millimetres, longer than the rod) are listed as
  refused, not compared.

Each plan is the library call ``rod-deploy plan`` makes (``plan_trajectory`` with ``PlannerSettings(method='nn',
start=..., friction=0.5)``); each deployment ``simulate_deployment`` with the library's and the benchmarks' settings
(5 mm edges, dt 0.02 s; ``rod-deploy simulate`` defaults to dt 0.05 s), friction 0.5, the rod at its own rest length;
scored with Eq. 17 (N = 50, the better direction), as ``rod-deploy evaluate``. Where the friction-limited start leaves
the pattern unchanged (a start within the friction bound) the two plans are checked to be identical and the
deployment is simulated once. CPU time is this process's (``time.process_time``), per run. Writes
``start_comparison.md`` and ``.json`` (after each shape, so a partial run leaves a partial table).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from acceptance_rehearsal import shapes as rehearsal_shapes, write_pattern  # noqa: E402
from results_dir import add_results_argument, results_path  # noqa: E402
from rod_deploy.deployment.metrics import eq17_error  # noqa: E402
from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment  # noqa: E402
from rod_deploy.planning.pattern_input import load_pattern  # noqa: E402
from rod_deploy.planning.rod_description import rod_description_from_dict  # noqa: E402
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
REF = Path(os.environ.get('ROD_DEPLOYMENT_REFERENCE',
                          Path(__file__).resolve().parents[2] / 'shared' / 'reference' / 'rod_deployment'))
WORK = ROOT / 'out' / 'start_comparison'
ROD3 = {'length': 0.89, 'radius': 0.002, 'L_gb': 0.034}
FRICTION = 0.5
#: excluded before running: a rigid copy of letter_e (translated and turned), it would count the e twice
EXCLUDED = {'letter_e_moved': 'a rigid copy of letter_e (the rehearsal: the same e_mean to 1e-4 cm)'}
PAPER = ('line', 'circle', 'sine', 'letterU', 'letterC', 'letterL', 'letterA')


def cases():
    """[(name, group, points (n, 2) as the CLI reads them)]: the rehearsal's shapes, then the paper's 7."""
    out = []
    WORK.mkdir(parents=True, exist_ok=True)
    for name, (pts, fmt, _) in rehearsal_shapes().items():
        if name in EXCLUDED:
            continue
        f = WORK / (f'{name}.csv' if fmt == 'csv' else f'{name}.txt')
        write_pattern(f, pts, fmt)
        out.append((name, 'rehearsal', f))
    for name in PAPER:
        out.append((name, 'paper', REF / 'patterns' / f'{name}.txt'))
    return out


def plan(points, rod, start):
    return plan_trajectory(points, rod, PlannerSettings(method='nn', start=start, friction=FRICTION))


def deploy(points, p, rod):
    c0 = time.process_time()
    res = simulate_deployment(p.t, p.position, p.quaternion, rod, SimulationSettings(friction=FRICTION))
    e = eq17_error(points, res.deployed_xy)
    return {'e_mean_cm': e['e_mean_cm'], 'sigma_cm': e['sigma_cm'], 'e_max_cm': e['e_max_cm'],
            'coverage': e['coverage'], 'sim_cpu_s': time.process_time() - c0, 'sim_wall_s': res.wall_time_s,
            'steps': res.steps, 'max_newton_iterations': res.max_newton_iterations,
            'halved_steps': res.halved_steps,
            'free_end_moved_cm': 100 * float(np.linalg.norm(res.deployed_xy[0] - points[0]))
            if len(res.deployed_xy) else float('nan')}


def plan_differences(a, t, rod):
    """How far the friction-limited plan ``a`` departs from the tangent plan ``t``: the largest change of the
    pattern nodes' kappa_bar and the arc length up to which it changes, the largest gripper move (same poses)."""
    out = {'start_kappa_bar_change_max': None, 'start_kappa_bar_changed_up_to_m': None, 'gripper_change_max_m': None}
    if a.pattern.kappa.shape == t.pattern.kappa.shape:
        dk = np.abs(a.pattern.kappa - t.pattern.kappa) * rod.gravito_bending_length_m
        k = np.flatnonzero(dk > 1e-6)
        out['start_kappa_bar_change_max'] = float(dk.max())
        out['start_kappa_bar_changed_up_to_m'] = float(a.pattern.s[k.max()]) if k.size else 0.0
    if a.position.shape == t.position.shape:
        out['gripper_change_max_m'] = float(np.linalg.norm(a.position - t.position, axis=1).max())
    return out


def run_case(name, group, path, rod, log):
    row = {'shape': name, 'group': group, 'pattern_file': str(path)}
    try:
        points = load_pattern(path)
    except ValueError as exc:
        row.update(status='refused', reason=str(exc))
        return row
    plans = {}
    for start in ('tangent', 'achievable'):
        c0 = time.process_time()
        try:
            plans[start] = plan(points, rod, start)
        except ValueError as exc:                   # PlanningError, OutOfTrainedRange: the CLI's exit 2
            row.update(status='refused', reason=f'{start}: {exc}')
            log(f'{name}: refused ({start}): {str(exc)[:160]}')
            return row
        row[f'plan_cpu_s_{start}'] = time.process_time() - c0
    replaced, dev = plans['achievable'].start_replacement()
    row.update(start_replaced_m=replaced, start_max_deviation_m=dev,
               pattern_max_abs_kappa_bar=float(abs(plans['tangent'].inputs[:, 2]).max()),
               planned_max_abs_kappa_bar=float(abs(plans['achievable'].inputs[:, 2]).max()))
    a, t = plans['achievable'], plans['tangent']
    same = (replaced == 0.0 and a.position.shape == t.position.shape and np.array_equal(a.position, t.position)
            and np.array_equal(a.quaternion, t.quaternion) and np.array_equal(a.t, t.t))
    row['identical_plans'] = bool(same)
    row.update(plan_differences(a, t, rod))
    for start in ('tangent', 'achievable'):
        if start == 'achievable' and same:
            row['achievable'] = dict(row['tangent'], sim_cpu_s=0.0, note='same plan as tangent, not simulated again')
            continue
        try:
            row[start] = deploy(points, plans[start], rod)
        except Exception as exc:                    # noqa: BLE001 - a failed simulation is a result
            row[start] = {'error': f'{type(exc).__name__}: {exc}'[:300]}
        log(f'{name} {start}: {row[start]}')
    row['status'] = 'compared'
    return row


def winner(row, tie_cm=0.005):
    """'achievable', 'tangent' or 'tie' (identical plans, or e_mean within ``tie_cm``)."""
    a, t = row['achievable'].get('e_mean_cm'), row['tangent'].get('e_mean_cm')
    if a is None or t is None:
        return '-'
    if row.get('identical_plans') or abs(a - t) < tie_cm:
        return 'tie'
    return 'achievable' if a < t else 'tangent'


def write_report(out, rows, total_cpu, total_wall):
    f = lambda v, fmt='.3f': '-' if v is None else format(v, fmt)  # noqa: E731
    lines = ['# Tangent start against the friction-limited start, `python benchmarks/start_comparison.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{os.getloadavg()[0]:.1f} at the end); {total_cpu:.0f} s CPU, {total_wall:.0f} s wall in all. Rod #3 '
             '(L_gb 0.034 m, radius 0.002 m, length 0.89 m), friction 0.5, nn; our DER with the rod at its own rest '
             'length (5 mm edges, dt 0.02 s, 0.01 m/s, friction regularisation 1e-4 m/s); Eq. 17 e_mean in cm '
             '(N = 50). "replaced": the length of the pattern\'s start the friction-limited start replaces / the '
             'largest distance of its curve from the pattern. Winner: the lower e_mean; "tie" when the plans are '
             'identical (a start within the friction bound is left unchanged: simulated once) or within 0.005 cm. '
             'CPU: simulation CPU seconds, tangent / achievable. Shapes: the paper\'s 7 (on which the default was '
             'chosen, with the stretched rest length) and every shape of the acceptance rehearsal\'s generator '
             '(`acceptance_rehearsal.shapes()`) but `letter_e_moved`, a rigid copy of `letter_e`; fixed before the '
             'first run.', '',
             '| shape | group | e_mean tangent cm | e_mean achievable cm | start_replaced_m | max deviation mm | '
             'start kappa_bar change (up to s m) | gripper change mm | pattern abs kappa_bar max | winner | '
             'free end moved cm (t / a) | sim CPU s (t / a) | notes |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        if r['status'] != 'compared':
            lines.append(f'| {r["shape"]} | {r["group"]} | - | - | - | - | - | - | - | refused | - | - | '
                         f'{r["reason"].replace("|", "/")[:200]} |')
            continue
        t, a = r['tangent'], r['achievable']
        notes = []
        for k, d in (('tangent', t), ('achievable', a)):
            if 'error' in d:
                notes.append(f'{k}: {d["error"]}')
            elif d.get('halved_steps'):
                notes.append(f'{k}: {d["halved_steps"]} halved steps')
        if r['identical_plans']:
            notes.append('identical plans')
        lines.append(f'| {r["shape"]} | {r["group"]} | {f(t.get("e_mean_cm"))} | {f(a.get("e_mean_cm"))} | '
                     f'{r["start_replaced_m"]:.3f} | {1000 * r["start_max_deviation_m"]:.1f} | '
                     f'{f(r.get("start_kappa_bar_change_max"), ".3f")} ({f(r.get("start_kappa_bar_changed_up_to_m"), ".3f")}) | '
                     f'{f(None if r.get("gripper_change_max_m") is None else 1000 * r["gripper_change_max_m"], ".1f")} | '
                     f'{r["pattern_max_abs_kappa_bar"]:.2f} | {winner(r)} | '
                     f'{f(t.get("free_end_moved_cm"), ".2f")} / {f(a.get("free_end_moved_cm"), ".2f")} | '
                     f'{f(t.get("sim_cpu_s"), ".0f")} / {f(a.get("sim_cpu_s"), ".0f")} | {"; ".join(notes)} |')
    lines += ['', 'Wins: the lower e_mean, ties within 0.005 cm (identical plans included); in brackets with ties '
                  'within 0.05 cm (a margin chosen after the results were seen, to show which wins are small). '
                  'Median difference: of e_mean tangent - e_mean achievable, per shape (> 0: the friction-limited '
                  'start better).', '',
              '| set | shapes compared | mean e_mean tangent cm | mean e_mean achievable cm | median difference cm | '
              'wins tangent | wins achievable | ties |', '|---|---|---|---|---|---|---|---|']
    ok = [r for r in rows if r['status'] == 'compared' and 'e_mean_cm' in r['tangent']
          and 'e_mean_cm' in r['achievable']]
    summary = {}
    for label, sel in (('paper\'s 7', [r for r in ok if r['group'] == 'paper']),
                       ('rehearsal shapes', [r for r in ok if r['group'] == 'rehearsal']),
                       ('all', ok),
                       ('all with the start replaced (start_replaced_m > 0)',
                        [r for r in ok if r['start_replaced_m'] > 0])):
        if not sel:
            continue
        w = [winner(r) for r in sel]
        w5 = [winner(r, 0.05) for r in sel]
        s = {'n': len(sel), 'mean_tangent': float(np.mean([r['tangent']['e_mean_cm'] for r in sel])),
             'mean_achievable': float(np.mean([r['achievable']['e_mean_cm'] for r in sel])),
             'median_difference': float(np.median([r['tangent']['e_mean_cm'] - r['achievable']['e_mean_cm']
                                                   for r in sel])),
             'wins_tangent': w.count('tangent'), 'wins_achievable': w.count('achievable'), 'ties': w.count('tie'),
             'wins_tangent_0.05': w5.count('tangent'), 'wins_achievable_0.05': w5.count('achievable'),
             'ties_0.05': w5.count('tie')}
        summary[label] = s
        lines.append(f'| {label} | {s["n"]} | {s["mean_tangent"]:.3f} | {s["mean_achievable"]:.3f} | '
                     f'{s["median_difference"]:+.3f} | {s["wins_tangent"]} ({s["wins_tangent_0.05"]}) | '
                     f'{s["wins_achievable"]} ({s["wins_achievable_0.05"]}) | {s["ties"]} ({s["ties_0.05"]}) |')
    out.write_text('\n'.join(lines) + '\n')
    out.with_suffix('.json').write_text(json.dumps({'rows': rows, 'summary': summary, 'cpu_s': total_cpu,
                                                    'wall_s': total_wall}, indent=1, default=str))
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--only', default='', help='comma-separated shape names (default: all)')
    ap.add_argument('--report-only', action='store_true',
                    help="rewrite the table from the last run's json (the plans, cheap, are made again for the "
                         "plan-difference columns; the deployments are not simulated again)")
    add_results_argument(ap)
    args = ap.parse_args()
    out = results_path(args, 'start_comparison.md')
    rod = rod_description_from_dict(dict(ROD3))
    if args.report_only:
        data = json.loads(out.with_suffix('.json').read_text())
        paths = {n: p for n, _, p in cases()}
        for r in data['rows']:
            if r['status'] == 'compared':
                pts = load_pattern(paths[r['shape']])
                a, t = plan(pts, rod, 'achievable'), plan(pts, rod, 'tangent')
                assert a.start_replacement() == (r['start_replaced_m'], r['start_max_deviation_m']), r['shape']
                r.update(plan_differences(a, t, rod))
        lines = write_report(out, data['rows'], data['cpu_s'], data['wall_s'])
        print('\n'.join(lines[-7:]))
        return
    rows = []
    c0, w0 = time.process_time(), time.perf_counter()

    def log(msg):
        print(msg, flush=True)

    for name, group, path in cases():
        if args.only and name not in args.only.split(','):
            continue
        rows.append(run_case(name, group, path, rod, log))
        write_report(out, rows, time.process_time() - c0, time.perf_counter() - w0)
    lines = write_report(out, rows, time.process_time() - c0, time.perf_counter() - w0)
    print('\n'.join(lines[-7:]))
    print(f'wrote {out}')


if __name__ == '__main__':
    main()
