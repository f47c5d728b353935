"""`rod-deploy simulate`: lay a rod along a gripper trajectory in our DER simulator; write the deployed shape.

    rod-deploy simulate --traj traj.csv --rod ROD.yaml [--friction MU] --out deployed.csv [--plot deployed.png]
                        [--pattern P | --start X Y] [--edge-length 0.005] [--dt 0.02] [--speed 0.01]

The trajectory follows CONTRACTS.md section 4 (``rod-deploy plan`` writes one). A trajectory that does not start
at the hanging pose (e.g. the published planner's, which start at the first grasp) needs the pattern's first point
(``--pattern`` or ``--start``). Prints one JSON line (deployed length, steps, wall time).
"""
from __future__ import annotations

import json

from rod_deploy.cli.main import CliError


def register(subparsers):
    p = subparsers.add_parser('simulate', help='simulate a deployment along a gripper trajectory (our DER)',
                              description=__doc__.split('\n\n')[0])
    p.add_argument('--traj', required=True, help='gripper trajectory CSV (t,x,y,z,qx,qy,qz,qw)')
    p.add_argument('--rod', required=True, help='rod description YAML')
    p.add_argument('--friction', type=float, default=None,
                   help='Coulomb coefficient with the table (default: the rod file\'s, else 0.5)')
    p.add_argument('--out', required=True, help='deployed shape CSV to write (x,y from the free end)')
    p.add_argument('--plot', help='PNG: prescribed pattern (with --pattern) vs deployed, and the gripper path')
    start = p.add_mutually_exclusive_group()
    start.add_argument('--pattern', help='the pattern (its first point is where the free end starts)')
    start.add_argument('--start', type=float, nargs=2, metavar=('X', 'Y'), help='free end start point [m]')
    p.add_argument('--edge-length', type=float, default=0.005, help='rod discretisation [m] (default 0.005)')
    # the library's step, SimulationSettings.dt_s (a test keeps them equal; not imported here, the simulator's import
    # would slow every subcommand): the tables were measured with it; at 0.05 s rod #3's letter U needed 2 halved steps
    p.add_argument('--dt', type=float, default=0.02, help='implicit Euler time step [s] (default 0.02, the library\'s)')
    p.add_argument('--speed', type=float, default=0.01,
                   help='gripper speed of the replay [m/s] (default 0.01, quasi-static)')
    p.add_argument('--hold-free-end', choices=('lead-in', 'always'), default='lead-in',
                   help='pin the free end during the lead-in only (default, CONTRACTS.md) or throughout (the paper '
                        'does so for a rope on the letter C: a free end cannot stay curved)')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    p.set_defaults(func=run)


def run(args) -> int:
    import numpy as np

    from rod_deploy.deployment.metrics import write_deployed_csv
    from rod_deploy.deployment.simulate import DeploymentError, SimulationSettings, simulate_deployment
    from rod_deploy.planning.pattern_input import load_pattern
    from rod_deploy.planning.rod_description import load_rod_description
    from rod_deploy.planning.trajectory_io import read_trajectory_csv

    for name in ('edge_length', 'dt', 'speed'):
        v = getattr(args, name)
        if not (np.isfinite(v) and v > 0):
            raise CliError(f'--{name.replace("_", "-")} must be positive, got {v}')
    if args.friction is not None and not (np.isfinite(args.friction) and args.friction >= 0):
        raise CliError(f'--friction must be >= 0, got {args.friction}')
    try:
        rod = load_rod_description(args.rod)
        t, p, q = read_trajectory_csv(args.traj)
        pattern = load_pattern(args.pattern) if args.pattern else None
    except ValueError as e:
        raise CliError(str(e)) from None
    start = tuple(pattern[0]) if pattern is not None else (tuple(args.start) if args.start else None)
    settings = SimulationSettings(edge_length_m=args.edge_length, dt_s=args.dt, max_gripper_speed_m_s=args.speed,
                                  friction=args.friction, start_xy=start, hold_free_end=args.hold_free_end)
    bar = None
    if not args.quiet:
        from tqdm import tqdm
        bar = tqdm(desc='simulate', unit='step', disable=None, mininterval=0.5)

    def progress(k, total):
        if bar is not None:
            bar.total = total
            bar.update(k - bar.n)

    try:
        result = simulate_deployment(t, p, q, rod, settings, progress)
    except DeploymentError as e:
        raise CliError(str(e)) from None
    finally:
        if bar is not None:
            bar.close()
    if len(result.deployed_xy) < 2:
        raise CliError('nothing was laid on the table (fewer than 2 rod nodes touch it at the end); '
                       'check that the trajectory brings the rod down to the table')
    write_deployed_csv(args.out, result.deployed_xy)
    summary = {'deployed': str(args.out), 'deployed_points': int(len(result.deployed_xy)),
               'deployed_length_m': float(np.sum(np.linalg.norm(np.diff(result.deployed_xy, axis=0), axis=1))),
               'friction': result.friction, 'steps': result.steps, 'newton_iterations': result.newton_iterations,
               'max_newton_iterations': result.max_newton_iterations, 'halved_steps': result.halved_steps,
               'wall_time_s': round(result.wall_time_s, 2)}
    if args.plot:
        from rod_deploy.deployment.plots import plot_deployment
        plot_deployment(args.plot, result, pattern, title=f'{args.traj}')
        summary['plot'] = str(args.plot)
    if pattern is not None:
        from rod_deploy.deployment.metrics import eq17_error
        summary.update({k: v for k, v in eq17_error(pattern, result.deployed_xy).items()
                        if k in ('e_mean_cm', 'sigma_cm', 'coverage')})
    print(json.dumps(summary))
    return 0
