"""Paper Table 2 in simulation: patterns x rods x friction x planners, each deployment simulated in our DER and
scored with Eq. 17 (N = 50).

    python benchmarks/deployment_table.py [--rods 2,3] [--friction medium] [--methods nn,intuitive,published]
                                          [--patterns all] [--start tangent|achievable] [--out-name NAME.md]
                                          [--plots] [--commit-results]
    python benchmarks/deployment_table.py --methods nn_refined [--refine 3] [--refine-offset arc_length|normal]
                                          [--refine-taper 0.03] [--save-traj DIR]

Patterns: the paper's 7 (``../shared/reference/rod_deployment/patterns``, read in place when present) and shapes of
our own made here by code (a spiral, the digit 2, the letter S, a loop that crosses itself; for the study of the
start, drawn after the friction-limited start was designed: the digit 6, the letter G, a tight wave). Rods: the paper's
Table 1 (#1 pink VPS L_gb 1.8 cm h 1.6 mm L 0.875 m, #2 green VPS 3.2 / 1.6 / 0.885, #3 rope 3.4 / 2.0 / 0.89).
Friction levels: low 0.2, medium 0.5, high 1.0. Planners: ours (``nn``, ``numeric``), the paper's ``intuitive``
baseline, and ``published``: the released planner's trajectories for the 7 patterns (rod #3 only, the rod they
were made for; replayed from the hanging pose above the pattern's first point). Our planners are told the row's
table friction (``PlannerSettings.friction``: the friction-limited start, the default, depends on it).
``nn_refined``: the nn plan refined with our DER in the loop (``rod_deploy.deployment.refinement``, what
``rod-deploy plan --refine`` runs; ``--refine`` template simulations after the unrefined plan's), the row's deployment
the best one simulated, its note the predicted e_mean before and after, the simulations and the CPU time.
``--save-traj DIR`` writes every trajectory for ``pyelastica_replay.py --traj-dir``. Writes a markdown table and a
plot per case (``--plots``).
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from results_dir import add_results_argument, results_path
from rod_deploy.deployment.metrics import eq17_error
from rod_deploy.deployment.refinement import RefinementSettings, refine_plan
from rod_deploy.deployment.simulate import (FRICTION_LEVELS, LAID_HEIGHT_TOLERANCE_M, SimulationSettings,
                                            simulate_deployment)
from rod_deploy.planning.pattern_input import load_pattern
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory, trajectory_times

#: the published patterns and trajectories, read in place (``ROD_DEPLOYMENT_REFERENCE`` overrides, e.g. from a worktree)
REF = Path(os.environ.get('ROD_DEPLOYMENT_REFERENCE',
                          Path(__file__).resolve().parents[2] / 'shared' / 'reference' / 'rod_deployment'))
RODS = {1: {'length': 0.875, 'radius': 0.0016, 'L_gb': 0.018},
        2: {'length': 0.885, 'radius': 0.0016, 'L_gb': 0.032},
        3: {'length': 0.89, 'radius': 0.002, 'L_gb': 0.034}}


def own_patterns():
    """Shapes of our own, in metres, starting at the origin."""
    out = {}
    th = np.linspace(0, 2.2 * np.pi, 400)
    r = 0.11 - 0.02 * th / np.pi
    out['spiral'] = np.column_stack([r * np.cos(th) - r[0], r * np.sin(th)])
    from scipy.interpolate import splev, splprep
    pts = np.array([[-0.08, 0.04], [-0.05, 0.1], [0.03, 0.12], [0.09, 0.07], [0.07, 0.0], [0.0, -0.06],
                    [-0.06, -0.13], [0.02, -0.16], [0.11, -0.16]])
    tck, _ = splprep(pts.T, s=0, k=3)
    digit2 = np.column_stack(splev(np.linspace(0, 1, 400), tck))
    out['digit2'] = digit2 - digit2[0]
    s = np.linspace(0, 1, 400)
    out['letterS'] = np.column_stack([0.08 * np.sin(2 * np.pi * s) * (1 - 0.2 * s), -0.4 * s])
    u = np.linspace(-1.2, 1.2, 400)                                   # a loop that crosses itself (alpha)
    loop = np.column_stack([0.18 * (u ** 2 - 1), 0.15 * u * (u ** 2 - 1) * 1.5])
    out['loop_crossing'] = loop - loop[0]
    # drawn for the start study (not used while the friction-limited start was designed): a curved start each
    pts = np.array([[0.06, 0.12], [0.0, 0.13], [-0.05, 0.08], [-0.065, 0.0], [-0.035, -0.06], [0.03, -0.065],
                    [0.055, -0.015], [0.025, 0.03], [-0.03, 0.025]])              # the digit 6
    tck, _ = splprep(pts.T, s=0, k=3)
    digit6 = np.column_stack(splev(np.linspace(0, 1, 400), tck))
    out['digit6'] = digit6 - digit6[0]
    th = np.linspace(0.25 * np.pi, 1.9 * np.pi, 300)                  # the letter G: an arc from its upper tip,
    g = np.column_stack([0.1 * np.cos(th), 0.1 * np.sin(th)])           # then a tighter turn (radius 3 cm) inwards
    phi = np.linspace(0.0, 0.5 * np.pi, 40)[1:] + th[-1]
    hook = g[-1] + 0.03 * np.column_stack([np.cos(phi) - np.cos(th[-1]), np.sin(phi) - np.sin(th[-1])])
    letter_g = np.vstack([g, hook])
    out['letterG'] = letter_g - letter_g[0]
    x = np.linspace(0, 0.5, 400)                                        # a wave of radius 5 cm at its crests,
    out['wave_tight'] = np.column_stack([x, 0.03 * np.sin(2 * np.pi * x / 0.24 + 1.0)])  # starting mid-bend
    return out


def all_patterns(selection='all'):
    """The published patterns (when the reference is present) and ours, by name; ``selection``: 'all' or
    comma-separated names."""
    patterns = {}
    if (REF / 'patterns').exists():
        for f in sorted((REF / 'patterns').glob('*.txt')):
            patterns[f.stem] = load_pattern(f)
    patterns.update(own_patterns())
    if selection != 'all':
        patterns = {k: v for k, v in patterns.items() if k in selection.split(',')}
    return patterns


def published_trajectory(name):
    d = np.loadtxt(REF / 'reference_outputs' / f'{name}_traj_NN.txt')
    q = d[:, 3:7] / np.linalg.norm(d[:, 3:7], axis=1, keepdims=True)
    for i in range(1, len(q)):
        if np.dot(q[i], q[i - 1]) < 0:
            q[i] = -q[i]
    return trajectory_times(d[:, :3], q, 0.01, 0.2), d[:, :3], q


def laid_strain(res, rod_length_m):
    """The deployed nodes' arc length over their material length (node index x L / N), minus 1; without the deployed
    shape's last point, which may lie between two nodes (the touch-down point)."""
    xy = res.deployed_xy[:-1]
    if len(xy) < 2:
        return float('nan')
    arc = float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))
    return arc / ((len(xy) - 1) * rod_length_m / (len(res.nodes) - 1)) - 1.0


def write_table(out, rows, t_all, args):
    lines = ['# Deployment in simulation (paper Table 2), `python benchmarks/deployment_table.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores; {time.perf_counter() - t_all:.0f} s in all. '
             'Our DER simulator (edge 5 mm, dt 0.02 s, gripper at 0.01 m/s, damping 2/s, regularised Coulomb '
             f'friction, regularisation velocity {args.friction_velocity:g} m/s; imperfection of the hanging rod {args.imperfection:g} m); the deployed shape: the nodes within '
             f'{1000 * LAID_HEIGHT_TOLERANCE_M:g} mm of lying on the table, from the free end, ended at the touch-down '
             'point (simulate.touchdown_cut); Eq. 17 with N = 50, the '
             'deployed curve cut at the pattern length; coverage = deployed / '
             f'pattern length. Self-contact ignored. Planner start: {args.start or PlannerSettings().start} '
             '(nn, numeric; the friction-limited start plans with the table friction of the row); planned curve: '
             f'{args.planned_curve or PlannerSettings().planned_curve} (PlannerSettings.planned_curve); its start '
             'point: ' + ('free' if (args.start_point or ('free' if PlannerSettings().free_start_point else 'fixed'))
                          == 'free' else 'fixed') + ' (PlannerSettings.free_start_point); drag '
             'compensation at bends (PlannerSettings.drag_compensation): '
             f'{args.drag_compensation or ("on" if PlannerSettings().drag_compensation else "off")}; friction share '
             f'of the start (PlannerSettings.friction_share): '
             f'{args.friction_share if args.friction_share is not None else PlannerSettings().friction_share:g}; '
             f'shear at q_C (PlannerSettings.shear): {args.shear or PlannerSettings().shear}.', '',
             '| rod | friction | pattern | planner | e_mean cm | sigma cm | coverage | sim s | note |',
             '|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        lines.append(f'| #{r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]:.3f} | {r[5]:.3f} | {r[6]:.2f} | {r[7]:.0f} | '
                     f'{r[8]} |')
    by = {}
    for r in rows:
        if np.isfinite(r[4]):
            by.setdefault(r[3], []).append(r[4])
    lines += ['', '| planner | cases | mean e_mean cm | max |', '|---|---|---|---|']
    for m, v in by.items():
        lines.append(f'| {m} | {len(v)} | {np.mean(v):.3f} | {np.max(v):.3f} |')
    out.write_text('\n'.join(lines) + '\n')
    return lines, by


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rods', default='3')
    ap.add_argument('--friction', default='medium')
    ap.add_argument('--methods', default='nn,intuitive,published')
    ap.add_argument('--patterns', default='all')
    ap.add_argument('--start', default=None, choices=('tangent', 'achievable'),
                    help="the planner's start (PlannerSettings.start; default: the planner's default)")
    ap.add_argument('--planned-curve', default=None, choices=('closest', 'spread'),
                    help="the curve the nodes are planned on (PlannerSettings.planned_curve; default: the planner's)")
    ap.add_argument('--start-point', default=None, choices=('free', 'fixed'),
                    help="the closest planned curve's first point fitted ('free') or held at the pattern's first "
                         "point ('fixed') (PlannerSettings.free_start_point; default: the planner's)")
    ap.add_argument('--drag-compensation', default=None, choices=('on', 'off'),
                    help="the planner's feed-forward against the drag at bends (PlannerSettings.drag_compensation, "
                         "planning/bend_drag.py; default: the planner's)")
    ap.add_argument('--friction-share', type=float, default=None,
                    help="share c of the friction the friction-limited start counts on (PlannerSettings.friction_share;"
                         " default: the planner's; the refusal check counts on min(c, 1))")
    ap.add_argument('--shear', default=None, choices=('moment_free', 'least_force'),
                    help="the lateral force the grasps apply at the connective node (PlannerSettings.shear; "
                         "'least_force' needs --methods numeric; default: the planner's)")
    ap.add_argument('--plots', action='store_true')
    ap.add_argument('--friction-velocity', type=float, default=SimulationSettings.friction_velocity_m_s,
                    help='regularisation velocity of Coulomb friction [m/s] (creep speed scale)')
    ap.add_argument('--imperfection', type=float, default=SimulationSettings.imperfection_m,
                    help='the hanging rod\'s imperfection [m] (0: a perfect rod)')
    ap.add_argument('--out-name', default='deployment_table.md', help='name of the results file')
    ap.add_argument('--refine', type=int, default=4, metavar='N',
                    help='method nn_refined: simulations of templates after the unrefined plan\'s (default 4)')
    ap.add_argument('--refine-offset', default=RefinementSettings.offset, choices=('arc_length', 'normal'))
    ap.add_argument('--refine-smoothing', type=float, default=RefinementSettings.smoothing_m,
                    help='Gaussian sigma of the correction along the pattern [m]')
    ap.add_argument('--refine-gain', type=float, default=RefinementSettings.gain)
    ap.add_argument('--refine-taper', type=float, default=RefinementSettings.start_taper_m,
                    help='the correction ramps up over this arc length from the free end [m]')
    ap.add_argument('--save-traj', metavar='DIR',
                    help='write every trajectory simulated as DIR/traj_PATTERN_METHOD_rodK_FRICTION.csv (for '
                         'pyelastica_replay.py --traj-dir)')
    add_results_argument(ap)
    args = ap.parse_args()
    start_used = args.start or PlannerSettings().start
    extra = {**({'start': args.start} if args.start else {}),
             **({'planned_curve': args.planned_curve} if args.planned_curve else {}),
             **({'free_start_point': args.start_point == 'free'} if args.start_point else {}),
             **({'drag_compensation': args.drag_compensation == 'on'} if args.drag_compensation else {}),
             **({'friction_share': args.friction_share} if args.friction_share is not None else {}),
             **({'shear': args.shear} if args.shear else {})}
    patterns = all_patterns(args.patterns)
    methods = args.methods.split(',')
    frictions = args.friction.split(',')
    out = results_path(args, args.out_name)
    rows = []
    t_all = time.perf_counter()
    for rod_id in (int(r) for r in args.rods.split(',')):
        rod = rod_description_from_dict(RODS[rod_id])
        for fr in frictions:
            for name, P in patterns.items():
                for method in methods:
                    if method == 'published' and (rod_id != 3 or not (REF / 'reference_outputs' /
                                                                      f'{name}_traj_NN.txt').exists()):
                        continue
                    t0, c0 = time.perf_counter(), time.process_time()
                    try:
                        refined_note = ''
                        if method == 'published':
                            t, p, q = published_trajectory(name)
                            start = tuple(P[0])
                        elif method == 'nn_refined':
                            planner = PlannerSettings(friction=FRICTION_LEVELS[fr], **extra)
                            best, record = refine_plan(
                                P, rod, plan_trajectory(P, rod, planner), planner,
                                SimulationSettings(friction=FRICTION_LEVELS[fr],
                                                   friction_velocity_m_s=args.friction_velocity),
                                RefinementSettings(simulations=args.refine, offset=args.refine_offset,
                                                   smoothing_m=args.refine_smoothing, gain=args.refine_gain,
                                                   start_taper_m=args.refine_taper))
                            t, p, q = best.deployment.t, best.deployment.position, best.deployment.quaternion
                            start = None
                            gains = ','.join(f'{h["gain"]:g}{"+" if h.get("accepted") else "-"}'
                                             for h in record['iterations'])
                            refined_note = (f'refined: predicted e_mean (directed) '
                                            f'{record["start_predicted_e_mean_cm"]:.3f} -> '
                                            f'{record["predicted_e_mean_cm"]:.3f} cm, {record["simulations"]} '
                                            f'simulations, CPU {record["cpu_time_s"]:.0f} s, gains {gains}; ')
                        else:
                            plan = plan_trajectory(P, rod, PlannerSettings(
                                method=method, friction=FRICTION_LEVELS[fr], **extra))
                            t, p, q, start = plan.t, plan.position, plan.quaternion, None
                        if args.save_traj:
                            from rod_deploy.planning.trajectory_io import write_trajectory_csv
                            Path(args.save_traj).mkdir(parents=True, exist_ok=True)
                            write_trajectory_csv(Path(args.save_traj) / f'traj_{name}_{method}_rod{rod_id}_{fr}.csv',
                                                 t, p, q)
                        if method == 'nn_refined':      # the best trajectory's simulation, not run again
                            res = best.result
                        else:
                            res = simulate_deployment(t, p, q, rod, SimulationSettings(
                                friction=FRICTION_LEVELS[fr], start_xy=start,
                                friction_velocity_m_s=args.friction_velocity, imperfection_m=args.imperfection))
                        e = eq17_error(P, res.deployed_xy)
                        row = (rod_id, fr, name, method, e['e_mean_cm'], e['sigma_cm'], e['coverage'],
                               time.perf_counter() - t0 if refined_note else res.wall_time_s,
                               f'{refined_note}laid strain {100 * laid_strain(res, rod.length_m):.2f} %; Newton '
                               f'max {res.max_newton_iterations}, halved steps {res.halved_steps}; CPU (plan and '
                               f'simulation) {time.process_time() - c0:.1f} s')
                        if args.plots:
                            from rod_deploy.deployment.plots import plot_deployment
                            tag = f'_{start_used}' if method in ('nn', 'numeric') else ''
                            plot_deployment(out.parent / f'deploy_{name}_{method}_rod{rod_id}_{fr}{tag}.png', res, P,
                                            f'{name}, {method}, rod #{rod_id}, {fr} friction')
                    except ValueError as exc:
                        row = (rod_id, fr, name, method, np.nan, np.nan, np.nan, time.perf_counter() - t0,
                               str(exc)[:90])
                    rows.append(row)
                    print(f'rod #{row[0]} {row[1]:6s} {row[2]:14s} {row[3]:10s} e_mean {row[4]:.3f} cm '
                          f'sigma {row[5]:.3f} coverage {row[6]:.2f} ({row[7]:.0f} s) {row[8]}', flush=True)
                    write_table(out, rows, t_all, args)
    lines, by = write_table(out, rows, t_all, args)
    print('\n'.join(lines[-2 - len(by):]))
    print(f'results: {out}')


if __name__ == '__main__':
    main()
