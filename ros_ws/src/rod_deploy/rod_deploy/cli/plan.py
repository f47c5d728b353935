"""`rod-deploy plan`: the gripper trajectory that lays a rod along a pattern (paper Alg. 4).

    rod-deploy plan --pattern P --rod ROD.yaml [--method nn|numeric|intuitive] --out traj.csv [--plot traj.png]
                    [--m-per-px S [--origin ROW COL] | --homography H.txt] [--object K]
                    [--step 0.005] [--smoothing 0.0005] [--speed 0.01] [--start tangent|achievable]
                    [--max-kappa-bar-rate R] [--shear moment_free|least_force] [--refine N]

P: a points file (x y [z] per line, metres, table frame) or an image of a drawn stroke / a photographed rod with
its mapping (as for ``rod-deploy perceive``). Writes the contract's trajectory CSV (t,x,y,z,qx,qy,qz,qw: table
frame, the held node of the rod, +z_gripper along which the rod leaves the gripper), starting at the hanging pose.
Methods: ``nn`` (default, the trained network), ``numeric`` (the optimal-grasp solver along the pattern with
curvature continuation: slow, exact), ``intuitive`` (the paper's baseline). A pattern that cannot be deployed (too
long for the rod, too sharp, a bend the table friction cannot hold so close to the free end, fewer than 3 points,
NaN, repeated points) gives one error line naming the point, exit 2, and no file. ``--start achievable`` (the
default): the start laid along the curve friction can hold near the free end (``planning/achievable_start.py``; the
rod file's ``friction``, else 0.5); ``--start tangent``: Alg. 4's start, every node on the pattern itself.
``--max-kappa-bar-rate``: how fast the planned curvature may change (``planning/curvature_rate.py``). ``--shear
least_force`` (numeric method; planning a median 19 s of CPU on the fresh rehearsal set against 3.7 s moment
free): each grasp applies the smallest horizontal force a moment-free gripper can at the connective node, a force
along the tangent allowed (``optimal_grasp.closest_shear_grasp``).
Bends where the table cannot hold the touch-down point are planned moved outwards by the drag predicted there
(``planning/bend_drag.py``; the JSON line's ``drag_compensation_max_offset_m``). The JSON line's
``planning_time_s`` is this plan's; ``startup_s`` the one-off loading before it (the network's weights, the compiled
kernels from numba's cache: 0.4-0.6 s per process here, ``planning.trajectory.warm_up``).

``--refine N`` (off by default: planning stays in milliseconds): simulation-in-the-loop refinement with our DER
(the declared rod, its file's friction else 0.5; the settings of ``rod-deploy simulate``): N simulations, the
unrefined plan's first, then plans for templates moved against the predicted deviation
(``rod_deploy.deployment.refinement``); the trajectory predicted best is written (the unrefined one if nothing
did better) and the JSON line's ``refine`` gives the predicted e_mean before and after, the simulations and the
CPU time. Each simulation of a 0.9 m rod takes 10-60 s here.
"""
from __future__ import annotations

import json
import sys

from rod_deploy.cli.main import CliError
from rod_deploy.planning.curvature_rate import DEFAULT_MAX_RATE, DEFAULT_RATE_FRICTION

#: a friction-limited start further than this from the pattern is reported on stderr [m]
START_NOTE_M = 0.005
#: a planned curve (what the grasps ask the rod to lay) further than this from the pattern is reported on stderr [m]
PLANNED_CURVE_NOTE_M = 0.01


def register(subparsers):
    p = subparsers.add_parser('plan', help='gripper trajectory for a pattern (Alg. 4): nn, numeric or intuitive',
                              description=__doc__.split('\n\n')[0])
    p.add_argument('--pattern', required=True, help='points file (x y [z], metres) or image of the pattern')
    p.add_argument('--rod', required=True, help='rod description YAML (length, radius, L_gb | loop_height | E+rho)')
    p.add_argument('--method', choices=('nn', 'numeric', 'intuitive'), default='nn')
    p.add_argument('--out', required=True, help='trajectory CSV to write')
    p.add_argument('--plot', help='PNG: the pattern and the gripper path (top view and side view)')
    p.add_argument('--m-per-px', type=float, help='image pattern: table metres per pixel')
    p.add_argument('--origin', type=float, nargs=2, metavar=('ROW', 'COL'), help='origin pixel for --m-per-px')
    p.add_argument('--homography', help='image pattern: 3x3 homography file')
    p.add_argument('--object', type=int, default=0, help='image pattern: which object (default 0, the longest)')
    p.add_argument('--step', type=float, default=0.005, help='node spacing along the pattern [m] (default 0.005)')
    p.add_argument('--smoothing', type=float, default=0.0005,
                   help='RMS distance the smoothing spline may keep from the pattern points [m] (default 0.0005)')
    p.add_argument('--speed', type=float, default=0.01, help='gripper speed [m/s] (default 0.01)')
    p.add_argument('--start', choices=('tangent', 'achievable'), default=None,
                   help="achievable (default): the start bent only as far as friction can hold it near the free end; "
                        "tangent: Alg. 4 from the pattern's first point")
    p.add_argument('--no-looser-start', action='store_true',
                   help='the friction-limited start counts on the friction bound as estimated (share 1) only; by '
                        'default it counts on 1.5 times it where that brings the planned curve more than 0.5 mm '
                        'nearer the pattern (the JSON line\'s start_friction_share)')
    p.add_argument('--max-kappa-bar-rate', type=float, default=None,
                   help='largest change of the planned kappa_bar per L_gb of pattern (default '
                        f'{DEFAULT_MAX_RATE:g} at friction {DEFAULT_RATE_FRICTION:g}, scaled by sqrt(friction / '
                        f'{DEFAULT_RATE_FRICTION:g}); inf: the pattern\'s own curvature, as Alg. 4)')
    p.add_argument('--planned-curve', choices=('closest', 'spread'), default=None,
                   help='closest (default): plan on the curve nearest the pattern within the rate limit and the '
                        'friction-limited start; spread: the pattern\'s points with its curvature spread by the limit')
    p.add_argument('--free-start-point', action='store_true',
                   help='let the closest planned curve\'s first point (where the free end is put down, the hanging '
                        'pose above it) leave the pattern\'s first point where that brings a curved start nearer '
                        'the pattern (letter C, rod #3: 6.8 mm); off by default: CONTRACTS.md starts a deployment '
                        'with the free end at the pattern\'s first point')
    p.add_argument('--shear', choices=('moment_free', 'least_force'), default=None,
                   help='moment_free (default): the paper\'s optimal grasps (no force along the tangent); '
                        'least_force (--method numeric): the grasps with the smallest horizontal force at the '
                        'connective node')
    p.add_argument('--refine', type=int, default=None, metavar='N',
                   help='refine the plan with N simulations of our DER (N >= 2: the unrefined plan and at least one '
                        'template; default off)')
    p.add_argument('--quiet', action='store_true', help='no progress bar (numeric method, --refine)')
    p.set_defaults(func=run)


def run(args) -> int:
    import numpy as np

    from rod_deploy.planning.neural_controller import OutOfTrainedRange
    from rod_deploy.planning.pattern_input import load_pattern
    from rod_deploy.planning.rod_description import load_rod_description
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory, warm_up
    from rod_deploy.planning.trajectory_io import write_trajectory_csv

    if args.refine is not None and args.refine < 2:
        raise CliError(f'--refine N: N simulations, the unrefined plan\'s and at least one of a refined template: '
                       f'N must be at least 2, got {args.refine}')
    if args.refine is not None and args.method == 'intuitive':
        raise CliError('--refine refines the planner\'s grasps (nn, numeric), not the intuitive baseline')
    try:
        rod = load_rod_description(args.rod)
        points = load_pattern(args.pattern, m_per_px=args.m_per_px, origin=args.origin, homography=args.homography,
                              object_index=args.object)
        settings = PlannerSettings(method=args.method, step_m=args.step, smoothing_m=args.smoothing,
                                   speed_m_s=args.speed, **({'start': args.start} if args.start else {}),
                                   **({'planned_curve': args.planned_curve} if args.planned_curve else {}),
                                   free_start_point=args.free_start_point, looser_start=not args.no_looser_start,
                                   **({'shear': args.shear} if args.shear else {}),
                                   **({'max_kappa_bar_rate': args.max_kappa_bar_rate}
                                      if args.max_kappa_bar_rate is not None else {}))
        startup_s = warm_up(rod, settings)
        bar = None
        if args.method == 'numeric' and not args.quiet:
            from tqdm import tqdm
            bar = tqdm(desc='numeric grasps', unit='node', disable=None)
        try:
            plan = plan_trajectory(points, rod, settings,
                                   progress=(lambda k: bar.update(1)) if bar is not None else None)
        finally:
            if bar is not None:
                bar.close()
    except OutOfTrainedRange as e:
        raise CliError(f'{e}') from None
    except ValueError as e:
        raise CliError(str(e)) from None
    refined, refine_record = _refine(args, points, rod, plan, settings) if args.refine else (None, None)
    written = refined.deployment if refined else plan
    write_trajectory_csv(args.out, written.t, written.position, written.quaternion)
    summary = {'trajectory': str(args.out), 'method': plan.method, 'poses': int(len(written.t)),
               'pattern_nodes': int(len(plan.pattern.s)), 'pattern_length_m': round(plan.pattern.length, 6),
               'duration_s': round(float(written.t[-1]), 3), 'lead_in_poses': plan.first_grasp_index,
               'ls_bar_range': [round(float(plan.inputs[:, 0].min()), 4), round(float(plan.inputs[:, 0].max()), 4)],
               'max_abs_kappa_bar': round(float(abs(plan.inputs[:, 2]).max()), 4), 'ks_bar': round(rod.ks_bar, 2),
               'planning_time_s': round(plan.timings_s['total'], 4), 'startup_s': round(startup_s, 4)}
    if plan.method != 'intuitive':                      # the intuitive baseline follows the pattern as given
        summary['start'] = settings.start
        # the share of the friction the friction-limited start counted on (PlannerSettings.looser_start)
        summary['start_friction_share'] = plan.friction_share
        summary['shear'] = settings.shear
        replaced_m, dev_m = plan.start_replacement()
        summary['start_replaced_m'] = round(replaced_m, 4)
        summary['start_max_deviation_m'] = round(dev_m, 4)
        summary['pattern_max_abs_kappa_bar'] = round(float(abs(plan.drawn_pattern.kappa).max())
                                                     * rod.gravito_bending_length_m, 4)
        dev_m, i = plan.asked_deviation()
        summary['planned_curve_max_deviation_m'] = round(dev_m, 4)
        summary['planned_curve_deviation_at'] = [round(float(v), 4) for v in plan.drawn_pattern.xy[i]]
        summary['free_end_start'] = [round(float(v), 6) for v in plan.pattern.xy[0]]
        summary['free_end_moved_m'] = round(float(np.linalg.norm(plan.pattern.xy[0] - plan.drawn_pattern.xy[0])), 6)
        # the drag compensation's template (planning/bend_drag.py): its largest distance from the drawn pattern
        summary['drag_compensation_max_offset_m'] = round(plan.drag_offset_max(), 4)
    if refined:
        summary['refine'] = refine_record
    if args.plot:
        from rod_deploy.deployment.plots import plot_plan
        if refined:
            plot_plan(args.plot, refined.plan, pattern_xy=points, predicted_xy=refined.deployed_xy,
                      predicted_e_mean_cm=refined.e_mean_cm)
        else:
            plot_plan(args.plot, plan)
        summary['plot'] = str(args.plot)
    print(json.dumps(summary))
    from rod_deploy.planning.pattern_input import sparse_points_note
    note = sparse_points_note(points, plan.drawn_pattern.xy)
    if note:
        print(f'rod-deploy plan: note: {note}', file=sys.stderr)
    if summary.get('start_max_deviation_m', 0.0) > START_NOTE_M:
        print(f'rod-deploy plan: note: the friction-limited start (--start achievable) replaces the first '
              f'{summary["start_replaced_m"]:.3f} m of the pattern by a curve up to '
              f'{1000 * summary["start_max_deviation_m"]:.0f} mm away from it (the free end cannot hold the '
              f'pattern\'s curvature there); --start tangent plans every node on the pattern', file=sys.stderr)
    if summary.get('planned_curve_max_deviation_m', 0.0) > PLANNED_CURVE_NOTE_M:
        x, y = summary['planned_curve_deviation_at']
        print(f'rod-deploy plan: note: the planned curve (the friction-limited start, bends widened by the curvature '
              f'rate limit) strays up to {100 * summary["planned_curve_max_deviation_m"]:.1f} cm from the pattern, at '
              f'({x:.4f}, {y:.4f}) m (|kappa_bar| up to {summary["pattern_max_abs_kappa_bar"]:.2g} on the pattern, '
              f'{summary["max_abs_kappa_bar"]:.2g} on the planned curve): the rod is laid along the planned curve, '
              f'not the pattern, there; a wider drawing or more table friction lets it follow the pattern',
              file=sys.stderr)
    kappa_bar_given = summary.get('pattern_max_abs_kappa_bar', summary['max_abs_kappa_bar'])
    if summary['max_abs_kappa_bar'] > 1.0:
        # the planned curve's largest bend: the replaced (friction-limited) start may bend more than the pattern
        what = 'the pattern bends'
        if summary['max_abs_kappa_bar'] > kappa_bar_given + 0.01:
            what = f'the planned curve (the pattern as drawn: up to {kappa_bar_given:.2g}, its replaced start more) bends'
        elif summary['max_abs_kappa_bar'] < kappa_bar_given - 0.01:    # the start and rate limit widened the bends
            what = f'the planned curve (the pattern as drawn: up to {kappa_bar_given:.2g}, widened within the limits) bends'
        print(f'rod-deploy plan: note: {what} with |kappa_bar| up to {summary["max_abs_kappa_bar"]:.2g} '
              f'(radius {rod.gravito_bending_length_m / summary["max_abs_kappa_bar"]:.3g} m); in our simulations '
              'deployments lose accuracy where |kappa_bar| > 1 (radius < L_gb): consider --smoothing or a larger '
              'drawing', file=sys.stderr)
    return 0


def _refine(args, points, rod, plan, settings):
    """(the best Candidate of ``args.refine`` simulations (module doc), the JSON line's record of the refinement)"""
    import numpy as np

    from rod_deploy.deployment.refinement import RefinementSettings, refine_plan
    from rod_deploy.deployment.simulate import FRICTION_LEVELS
    from rod_deploy.cli.progress import simulations_progress
    try:
        with simulations_progress(args.quiet) as progress:
            best, record = refine_plan(np.asarray(points)[:, :2], rod, plan, settings, None,   # simulate's defaults
                                       RefinementSettings(simulations=args.refine - 1), progress)
    except ValueError as e:
        raise CliError(f'refining the plan: {e}') from None
    return best, {
        'simulations': record['simulations'], 'refined': best.replanned,
        'predicted_e_mean_cm_before': round(record['start_predicted_e_mean_cm'], 4),
        'predicted_e_mean_cm_after': round(record['predicted_e_mean_cm'], 4),
        'friction': rod.friction if rod.friction is not None else FRICTION_LEVELS['medium'],
        'cpu_time_s': round(record['cpu_time_s'], 1), 'wall_time_s': round(record['wall_time_s'], 1),
        'iterations': record['iterations']}
