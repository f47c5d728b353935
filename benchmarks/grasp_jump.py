"""Why the planned gripper jumps, and what drags the laid rod (issue #10: the acceptance rehearsal's 10 cm hook).

    python benchmarks/grasp_jump.py [--deploy] [--jobs 2] [--commit-results]
    python benchmarks/grasp_jump.py --plot [--commit-results]      # grasp_jump.png: digit 2 and tight wave

Planning only (seconds): for the rehearsal's hook, our digit 2 and tight wave and the paper's 7 patterns (rod #3,
0.89 m, L_gb 3.4 cm, friction 0.5), the largest gripper step between two consecutive pattern nodes (5 mm) with the
planner before this study (``max_kappa_bar_rate=inf``, no friction check) and now (the defaults), where it happens
(arc length, ls_bar, kappa_bar on both sides); how far the optimal grasp moves per unit of kappa_bar at several
ls_bar (the network, a finite difference); whether the network and the numeric solver agree on both sides of the
hook's largest jump (a change of branch of the optimal grasp would show there); how far the straight chord between
two 5 mm poses strays from the optimal grasps of the nodes in between (planned at 0.5 mm).

``--deploy``: deployments in our DER simulator (``simulate_deployment``, its defaults: 5 mm edges, dt 0.02 s,
0.01 m/s, friction regularisation 1e-6 m/s), scored with Eq. 17 (N = 50): the same trajectories on tables of higher
friction (is the jump or the friction the cause?), a straight lead of 10-30 cm followed by a curl of radius 1.7 cm
(kappa_bar 2; drawn here for this study), the curvature-rate limit at 1, 0.5 and 0.25 per L_gb, and the paper's 7
and our own shapes with the new defaults. Writes ``grasp_jump.md`` (and ``grasp_jump.json``).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from multiprocessing import Pool

import numpy as np

from acceptance_rehearsal import shapes as rehearsal_shapes
from deployment_table import RODS, all_patterns
from results_dir import add_results_argument, results_path
from rod_deploy.deployment.metrics import eq17_error
from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment
from rod_deploy.planning.curvature_rate import DEFAULT_MAX_RATE
from rod_deploy.planning.neural_controller import load_grasp_network
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, PlanningError, plan_trajectory

MU = 0.5
ROD = dict(RODS[3], friction=MU)
#: the planner before this study: the pattern's own curvature, no friction check
BEFORE = {'max_kappa_bar_rate': np.inf, 'check_friction': False}
PAPER = ('circle', 'letterA', 'letterC', 'letterL', 'letterU', 'line', 'sine')


def lead_curl(lead_m, radius_m=0.017):
    """A straight lead of ``lead_m`` along +y, then a half turn to the left of radius ``radius_m``."""
    n = max(int(lead_m / 0.001), 3)
    line = np.column_stack([np.zeros(n), np.linspace(0.0, lead_m, n)])
    th = np.linspace(0.0, np.pi, 100)[1:]
    arc = np.column_stack([-radius_m + radius_m * np.cos(th), lead_m + radius_m * np.sin(th)])
    return np.vstack([line, arc])


def patterns():
    out = all_patterns('all')
    rehearsal = rehearsal_shapes()
    out['hook_10cm'] = rehearsal['hook_10cm'][0]
    out['zigzag_4_corners'] = rehearsal['zigzag_4_corners'][0]
    for lead in (10, 15, 20, 30):
        out[f'lead{lead}_curl'] = lead_curl(lead / 100)
    return out


def largest_step(plan):
    k = plan.first_grasp_index
    step = np.linalg.norm(np.diff(plan.position[k:], axis=0), axis=1)
    i = int(np.argmax(step))
    return i, float(step[i])


def local_step(plan, rod):
    """The largest move [m] of the grasp between two nodes in the pattern's local frame."""
    return float(np.linalg.norm(np.diff(plan.grasp_position, axis=0), axis=1).max()) * rod.gravito_bending_length_m


def planning_study(pats, rod):
    lines = ['## Why the gripper jumps (planning only)', '',
             'Largest gripper move between two consecutive pattern nodes (5 mm apart), rod #3, friction 0.5. '
             '"before": the pattern\'s own curvature (`max_kappa_bar_rate=inf`, no friction check); "now": the '
             'defaults (curvature rate limit, friction check).', '',
             '"local": the largest move of the grasp in the pattern\'s local frame (q_bar L_gb), i.e. without the '
             'gripper\'s orbit about the contact point as the tangent turns.', '',
             '| pattern | before: step cm | local cm | at s m | ls_bar | kappa_bar (node, next) | now: step cm | '
             'local cm | now |', '|---|---|---|---|---|---|---|---|---|']
    for name in ('hook_10cm', 'digit2', 'wave_tight', 'letterG', 'digit6') + PAPER:
        b = plan_trajectory(pats[name], rod, PlannerSettings(**BEFORE))
        i, st = largest_step(b)
        try:
            a = plan_trajectory(pats[name], rod, PlannerSettings())
            now_step, now_local, now = f'{100 * largest_step(a)[1]:.1f}', f'{100 * local_step(a, rod):.1f}', 'planned'
        except PlanningError as e:
            now_step, now_local, now = '-', '-', f'refused: {e}'
        lines.append(f'| {name} | {100 * st:.1f} | {100 * local_step(b, rod):.1f} | {b.pattern.s[i]:.3f} | '
                     f'{b.inputs[i, 0]:.1f} | {b.inputs[i, 2]:.2f}, {b.inputs[i + 1, 2]:.2f} | {now_step} | '
                     f'{now_local} | {now} |')
    net = load_grasp_network()
    ks = rod.ks_bar
    lines += ['', 'How far the optimal grasp moves per unit of kappa_bar (the network, kappa_bar 0 -> 1 and 1 -> 2): '
              '|delta q_bar| in L_gb (in cm for rod #3)', '', '| ls_bar | 0 -> 1 | 1 -> 2 |', '|---|---|---|']
    for ls in (2.0, 5.0, 12.0, 25.0):
        p, _ = net.predict(np.full(3, ls), np.full(3, ks), np.array([0.0, 1.0, 2.0]))
        d = np.linalg.norm(np.diff(p, axis=0), axis=1)
        lines.append(f'| {ls:g} | {d[0]:.2f} ({100 * d[0] * rod.gravito_bending_length_m:.1f}) | '
                     f'{d[1]:.2f} ({100 * d[1] * rod.gravito_bending_length_m:.1f}) |')
    # branch check: the numeric solver (curvature continuation from the straight-line optimum) on both sides
    from rod_deploy.planning.optimal_grasp import optimal_grasp
    b = plan_trajectory(pats['hook_10cm'], rod, PlannerSettings(**BEFORE))
    i, _ = largest_step(b)
    lines += ['', f'Network vs numeric solver at the hook\'s largest jump (nodes {i}, {i + 1}):', '',
              '| node | ls_bar | kappa_bar | network q_bar | numeric q_bar | difference L_gb |',
              '|---|---|---|---|---|---|']
    for j in (i, i + 1):
        ls, _, kb = b.inputs[j]
        g = optimal_grasp(ls, kb, ks, check_stability=False)
        pn = b.grasp_position[j]
        lines.append(f'| {j} | {ls:.2f} | {kb:.3f} | {np.round(pn, 3).tolist()} | {np.round(g.position, 3).tolist()} '
                     f'| {np.linalg.norm(pn - g.position):.3f} |')
    lines += ['', 'The straight chord between two 5 mm poses against the optimal grasps of the nodes in between '
              '(planned at 0.5 mm, tangent start so that both spacings plan the same curve):', '',
              '| pattern | largest 5 mm step cm | chord off the grasps cm | largest 0.5 mm step cm |',
              '|---|---|---|---|']
    for name in ('hook_10cm', 'digit2', 'wave_tight', 'letterA'):
        fine = plan_trajectory(pats[name], rod, PlannerSettings(step_m=0.0005, start='tangent', **BEFORE))
        p = fine.position[fine.first_grasp_index:]
        c = p[::10]
        dev = 0.0
        for k in range(len(c) - 1):
            seg, a0, d = p[10 * k:10 * k + 11], c[k], c[k + 1] - c[k]
            if np.linalg.norm(d) > 1e-12:
                t = np.clip((seg - a0) @ d / (d @ d), 0.0, 1.0)
                dev = max(dev, float(np.max(np.linalg.norm(seg - (a0 + t[:, None] * d), axis=1))))
        lines.append(f'| {name} | {100 * np.linalg.norm(np.diff(c, axis=0), axis=1).max():.1f} | {100 * dev:.2f} | '
                     f'{100 * np.linalg.norm(np.diff(p, axis=0), axis=1).max():.2f} |')
    return lines


def deployment_cases():
    """(pattern, label, planner settings, table friction in the simulation)."""
    cases = []
    for mu in (0.5, 2.0, 5.0):
        cases.append(('hook_10cm', 'before', BEFORE, mu))
    cases += [('hook_10cm', 'now', {}, 0.5), ('hook_10cm', 'now', {'friction': 5.0}, 5.0),
              ('hook_10cm', 'rate 0.35', {'friction': 5.0, 'max_kappa_bar_rate': 0.35}, 5.0)]
    for lead in (10, 15, 20):
        cases += [(f'lead{lead}_curl', 'before', BEFORE, 0.5), (f'lead{lead}_curl', 'now', {}, 0.5)]
    cases += [('digit2', 'before', BEFORE, 5.0), ('wave_tight', 'before', BEFORE, 2.0),
              ('digit2', 'before, 1 mm nodes', dict(BEFORE, step_m=0.001), 0.5)]
    for name in ('digit2', 'wave_tight', 'letterA', 'lead30_curl'):
        cases.append((name, 'before', BEFORE, 0.5))
        for rate in (0.5, 0.35, 0.25):
            cases.append((name, f'rate {rate:g}' + (' (now)' if rate == DEFAULT_MAX_RATE else ''),
                          {'max_kappa_bar_rate': rate}, 0.5))
    for name in ('circle', 'letterC', 'letterL', 'letterU', 'line', 'sine', 'spiral', 'letterS', 'loop_crossing',
                 'digit6', 'letterG'):
        cases.append((name, 'now', {}, 0.5))
    # the rehearsal's zig-zag given by its 4 corners (never simulated there), now refused at friction 0.5
    cases += [('zigzag_4_corners', 'before', BEFORE, 0.5), ('zigzag_4_corners', 'now', {}, 0.5)]
    # the rate limit's scaling with friction (sqrt(mu / 0.5)) at the paper's low and high friction
    for mu in (0.2, 1.0):
        for name in ('digit2', 'letterA'):
            cases += [(name, 'before', dict(BEFORE, friction=mu), mu), (name, 'now', {'friction': mu}, mu)]
    return cases


def deploy(case):
    name, label, kw, mu = case
    rod = rod_description_from_dict(ROD)
    P = patterns()[name]
    t0 = time.perf_counter()
    try:
        plan = plan_trajectory(P, rod, PlannerSettings(**kw))
    except PlanningError as e:
        return dict(pattern=name, label=label, sim_friction=mu, refused=str(e))
    res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod, SimulationSettings(friction=mu))
    e = eq17_error(P, res.deployed_xy)
    return dict(pattern=name, label=label, sim_friction=mu, e_mean_cm=e['e_mean_cm'], sigma_cm=e['sigma_cm'],
                coverage=e['coverage'], free_end_moved_cm=100 * float(np.linalg.norm(res.deployed_xy[0] - P[0])),
                max_step_cm=100 * largest_step(plan)[1], wall_s=time.perf_counter() - t0)


def plot(path, jobs):
    """Digit 2 and tight wave at friction 0.5, before and now: pattern, deployed shapes, gripper paths (top view)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    cases = [(n, lab, kw) for n in ('digit2', 'wave_tight') for lab, kw in (('before', BEFORE), ('now', {}))]
    with Pool(jobs) as pool:
        runs = pool.map(_deploy_xy, cases)
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.5))
    pats = patterns()
    for ax, name in zip(axes, ('digit2', 'wave_tight')):
        P = pats[name]
        ax.plot(P[:, 0], P[:, 1], color='0.6', lw=4, label='pattern')
        for (n, lab, _), (xy, grip, e) in zip(cases, runs):
            if n != name:
                continue
            c = 'tab:red' if lab == 'before' else 'tab:blue'
            ax.plot(xy[:, 0], xy[:, 1], color=c, lw=1.5, label=f'deployed, {lab} (e_mean {e:.2f} cm)')
            ax.plot(grip[:, 0], grip[:, 1], color=c, lw=0.8, ls='--', label=f'gripper, {lab}')
        ax.set_aspect('equal')
        ax.set_title(f'{name}, rod #3, friction 0.5')
        ax.set_xlabel('x [m]')
        ax.set_ylabel('y [m]')
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)


def _deploy_xy(case):
    name, _, kw = case
    rod = rod_description_from_dict(ROD)
    P = patterns()[name]
    plan = plan_trajectory(P, rod, PlannerSettings(**kw))
    res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod, SimulationSettings(friction=MU))
    return res.deployed_xy, plan.position[plan.first_grasp_index:], eq17_error(P, res.deployed_xy)['e_mean_cm']


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--deploy', action='store_true', help='also run the deployments (about 20 min on 2 cores)')
    ap.add_argument('--jobs', type=int, default=2)
    ap.add_argument('--select', help='run only the deployments whose "pattern label friction" contains one of these '
                                     'comma-separated texts, and replace those rows in the grasp_jump.json there')
    ap.add_argument('--from-json', help='the deployments from an earlier run\'s grasp_jump.json (rewrites the '
                                        'planning study with the current code)')
    ap.add_argument('--plot', action='store_true', help='only the plot grasp_jump.png (4 deployments)')
    add_results_argument(ap)
    args = ap.parse_args()
    if args.plot:
        plot(results_path(args, 'grasp_jump.png'), args.jobs)
        return
    t_all = time.perf_counter()
    rod = rod_description_from_dict(ROD)
    pats = patterns()
    lines = planning_study(pats, rod)
    rows = []
    if args.from_json:
        rows = json.loads(open(args.from_json).read())
    elif args.deploy:
        cases = deployment_cases()
        if args.select:
            cases = [c for c in cases if any(t in f'{c[0]} {c[1]} {c[3]:g}' for t in args.select.split(','))]
        with Pool(args.jobs) as pool:
            for r in pool.imap(deploy, cases):
                rows.append(r)
                print(json.dumps(r), flush=True)
        if args.select:
            key = lambda r: (r['pattern'], r['label'], r['sim_friction'])
            new = {key(r): r for r in rows}
            old = json.loads(results_path(args, 'grasp_jump.json').read_text())
            rows = [new.pop(key(r), r) for r in old] + list(new.values())
    if rows:
        lines += ['', '## Deployments (our DER, Eq. 17)', '',
                  '"before": the planner before this study; "rate R": the curvature rate limit R per L_gb and the '
                  f'friction check; "now": the defaults (rate {DEFAULT_MAX_RATE:g} at friction 0.5, scaled by '
                  'sqrt(friction / 0.5); friction check). Friction: the '
                  'table\'s in the simulation; the planner plans with 0.5 unless told otherwise. Before (the '
                  'committed tables, same simulator settings): line 0.033, circle 0.046, U 0.080, L 0.157, sine '
                  '0.191, C 0.278, A 0.843; spiral 0.122, S 0.087, loop 0.255, digit 6 0.874, G 0.295 cm.', '',
                  '| pattern | planner | friction | e_mean cm | sigma cm | coverage | free end moved cm | '
                  'largest gripper step cm |', '|---|---|---|---|---|---|---|---|']
        for r in rows:
            if 'refused' in r:
                lines.append(f'| {r["pattern"]} | {r["label"]} | {r["sim_friction"]:g} | refused: {r["refused"]} '
                             f'| | | | |')
            else:
                lines.append(f'| {r["pattern"]} | {r["label"]} | {r["sim_friction"]:g} | {r["e_mean_cm"]:.3f} | '
                             f'{r["sigma_cm"]:.3f} | {r["coverage"]:.2f} | {r["free_end_moved_cm"]:.2f} | '
                             f'{r["max_step_cm"]:.1f} |')
    head = ['# Gripper jumps and the laid rod (issue #10), `python benchmarks/grasp_jump.py' +
            (' --deploy`' if args.deploy or args.from_json else '`'), '',
            f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
            f'{os.getloadavg()[0]:.1f} at the end); {time.perf_counter() - t_all:.0f} s in all'
            + (f' (the deployments read from {args.from_json}, written by the `--deploy` runs that the commit '
               'adding it names; the planning study rerun)' if args.from_json else '')
            + (f' (only the deployments matching --select {args.select!r} run now, the other rows from the earlier '
               'full run)' if args.select else '') + '.', '']
    out = results_path(args, 'grasp_jump.md')
    out.write_text('\n'.join(head + lines) + '\n')
    if rows and not args.from_json:
        out.with_suffix('.json').write_text(json.dumps(rows, indent=1) + '\n')
    print('\n'.join(head + lines))


if __name__ == '__main__':
    main()
