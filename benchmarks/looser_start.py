"""The looser friction-limited start (``PlannerSettings.looser_start``, issue #10) on the development shapes: each
shape planned with it off (the planner before it: the start counts on ``friction_share`` 1) and on (1.5 where that
brings the planned curve more than 0.5 mm nearer the pattern); the rows whose two trajectories differ simulated in
our DER (the defaults of ``rod-deploy simulate``), Eq. 17 e_mean against the pattern points; a row whose two
trajectories are identical (array equality of t, positions, quaternions) is reported as such, not simulated.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/looser_start.py [--friction 0.5] \
        [--sets fresh,original,paper,own] [--rods 2,3] [--out-name looser_start.md] [--commit-results]

Sets: ``fresh`` the round-9 fresh rehearsal shapes on their rods (``acceptance_rehearsal.FRESH_RODS``, the rod's
L_gb), ``original`` the first rehearsal's shapes on their rods (nn runs of ``acceptance_rehearsal.RUNS`` on rods
#1-#3), ``paper`` and ``own`` the paper's 7 and our 7 (``deployment_table.all_patterns``) on ``--rods``. All of them
are development data: the rule was chosen on them. "planned mean": the mean distance of the curve the grasps ask for
from the processed pattern at equal arc length (the rule's measure).
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


def cases(sets, rods):
    import acceptance_rehearsal as ar
    from deployment_table import RODS, all_patterns
    out = []
    if 'fresh' in sets:
        shp = ar.fresh_shapes()
        for name, (rod, _) in ar.FRESH_RODS.items():
            out.append(('fresh', name, rod, shp[name][0], ar.RODS[rod]))
    if 'original' in sets:
        shp = ar.shapes()
        seen = set()
        for run in ar.RUNS:
            name, rod, method = run[0], run[1], run[3]
            if method != 'nn' or len(run) > 5 or rod == 'cable' or (name, rod) in seen or not run[4]:
                continue
            seen.add((name, rod))
            out.append(('original', name, rod, shp[name][0], ar.RODS[rod]))
    for which in ('paper', 'own'):
        if which in sets:
            from deployment_table import own_patterns
            own = own_patterns()
            for name, pts in all_patterns().items():
                if (name in own) == (which == 'own'):
                    for k in rods:
                        out.append((which, name, f'rod{k}', pts, RODS[k]))
    return out


def main():
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--friction', type=float, default=0.5)
    ap.add_argument('--sets', default='fresh,original,paper,own')
    ap.add_argument('--rods', default='2,3', help='rods of the paper and own sets')
    ap.add_argument('--timing', action='store_true',
                    help='plan only: the median CPU time of 3 plans per row, off and on (no simulation); '
                         'writes --out-name (default looser_start_cost.md)')
    ap.add_argument('--out-name', default=None)
    add_results_argument(ap)
    args = ap.parse_args()
    out = results_path(args, args.out_name or ('looser_start_cost.md' if args.timing else 'looser_start.md'))
    mu = args.friction
    if args.timing:
        return timing(out, args)
    rows, t_all = [], time.perf_counter()
    for group, name, rod_name, pts, rd in cases(args.sets.split(','), [int(k) for k in args.rods.split(',')]):
        rod = rod_description_from_dict({'length': rd['length'], 'radius': rd['radius'], 'L_gb': rd['L_gb'],
                                         'friction': mu})
        row = {'group': group, 'shape': name, 'rod': rod_name}
        plans = {}
        for key, on in (('off', False), ('on', True)):
            try:
                plans[key] = plan_trajectory(pts, rod, PlannerSettings(friction=mu, looser_start=on))
            except ValueError as e:
                plans[key] = None
                row['note'] = f'refused: {str(e)[:90]}'
        if plans['off'] is None or plans['on'] is None:
            rows.append(row)
            continue
        for key, p in plans.items():
            row[f'planned_{key}'] = float(np.mean(np.linalg.norm(
                np.column_stack([np.interp(p.drawn_pattern.s, p.pattern.s, p.asked_xy[:, k]) for k in range(2)])
                - p.drawn_pattern.xy, axis=1)))
        row['share'] = plans['on'].friction_share
        a, b = plans['off'], plans['on']
        if (np.array_equal(a.t, b.t) and np.array_equal(a.position, b.position)
                and np.array_equal(a.quaternion, b.quaternion)):
            row['note'] = 'identical trajectories: not simulated'
        else:
            cpu = time.process_time()
            for key, p in plans.items():
                res = simulate_deployment(p.t, p.position, p.quaternion, rod, SimulationSettings(friction=mu))
                row[f'e_{key}'] = eq17_error(pts, res.deployed_xy)['e_mean_cm']
            row['note'] = f'CPU {time.process_time() - cpu:.0f} s (both)'
            print(f"{group} {name} {rod_name}: {row['e_off']:.3f} -> {row['e_on']:.3f} cm", flush=True)
        rows.append(row)
        write(out, rows, args, t_all)
    write(out, rows, args, t_all)
    print(f'results: {out}')


def timing(out, args):
    """The planning CPU time with the looser start off and on (median of 3 plans per row, after one warm-up)."""
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory
    lines = [f'# Planning cost of the looser start, `python benchmarks/looser_start.py --timing --friction '
             f'{args.friction:g} --sets {args.sets} --rods {args.rods}`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs; CPU time of '
             '`plan_trajectory` (nn), median of 3 per row after a warm-up, in-process.', '',
             '| set | shape | rod | CPU s off | CPU s on | start share (on) |', '|---|---|---|---|---|---|']
    cpu = {False: [], True: []}
    warm = None
    for group, name, rod_name, pts, rd in cases(args.sets.split(','), [int(k) for k in args.rods.split(',')]):
        rod = rod_description_from_dict({'length': rd['length'], 'radius': rd['radius'], 'L_gb': rd['L_gb'],
                                         'friction': args.friction})
        row = {}
        for on in (False, True):
            ts = []
            for k in range(3 if warm else 4):
                t = time.process_time()
                try:
                    plan = plan_trajectory(pts, rod, PlannerSettings(friction=args.friction, looser_start=on))
                    row['share'] = plan.friction_share
                except ValueError:
                    row['share'] = 'refused'
                ts.append(time.process_time() - t)
            warm = True
            row[on] = float(np.median(ts[-3:]))
            cpu[on].append(row[on])
        lines.append(f'| {group} | {name} | {rod_name} | {row[False]:.3f} | {row[True]:.3f} | {row["share"]} |')
    lines += ['', f'Median over the {len(cpu[False])} rows: off {np.median(cpu[False]):.3f} s, on '
              f'{np.median(cpu[True]):.3f} s; largest: off {max(cpu[False]):.3f} s, on {max(cpu[True]):.3f} s; load '
              f'average {os.getloadavg()[0]:.1f} at the end.']
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


def write(out, rows, args, t_all):
    def f(v, m=1.0):
        return '-' if v is None else f'{m * v:.3f}'
    lines = [f'# The looser friction-limited start, `python benchmarks/looser_start.py --friction {args.friction:g} '
             f'--sets {args.sets} --rods {args.rods}`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{os.getloadavg()[0]:.1f} at writing); {time.perf_counter() - t_all:.0f} s in all. Table friction '
             f'{args.friction:g} (planner and simulator), our DER with the defaults of `rod-deploy simulate`, nn '
             'planner with its defaults; "off": `looser_start=False` (the planner before the change), "on": the '
             'default. Eq. 17 e_mean in cm (N = 50) against the pattern points; "planned mean" cm: mean distance of '
             'the curve the grasps ask for from the processed pattern at equal arc length. Development data (the '
             'rule was chosen on these shapes).', '',
             '| set | shape | rod | start share (on) | planned mean off | planned mean on | e_mean off | e_mean on | '
             'change | note |', '|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        ch = f"{r['e_on'] - r['e_off']:+.3f}" if 'e_on' in r else '0'
        lines.append(f"| {r['group']} | {r['shape']} | {r['rod']} | {r.get('share', '-')} | "
                     f"{f(r.get('planned_off'), 100)} | {f(r.get('planned_on'), 100)} | {f(r.get('e_off'))} | "
                     f"{f(r.get('e_on'))} | {ch} | {r.get('note', '')} |")
    sim = [r for r in rows if 'e_on' in r]
    if sim:
        off, on = np.array([r['e_off'] for r in sim]), np.array([r['e_on'] for r in sim])
        lines += ['', f'Rows whose trajectories differ: {len(sim)} of {len(rows)}; their mean e_mean {off.mean():.3f} '
                  f'-> {on.mean():.3f} cm; better by more than 0.005 cm: {int(np.sum(on < off - 0.005))}, worse by '
                  f'more than 0.005 cm: {int(np.sum(on > off + 0.005))}.']
    out.write_text('\n'.join(lines) + '\n')


if __name__ == '__main__':
    main()
