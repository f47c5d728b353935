"""`rod-deploy correct`: the deployment's closed loop: explain a deployed shape, fit the effect, replan.

    rod-deploy correct --pattern P --rod ROD.yaml --deployed deployed.csv [--traj traj.csv] --out DIR
                       [--replan] [--simulate] [--effects natural_curvature,L_gb,friction] [--noise-floor-mm 0.5]
                       [--friction MU] [--edge-length 0.005] [--dt 0.02] [--speed 0.01] [--start tangent|achievable]

The deployed shape (contract CSV x,y, from ``rod-deploy simulate`` or ``rod-deploy perceive``) is compared with our
simulator replaying the trajectory that laid it (``--traj``; default: the planner's ``nn`` trajectory for the
declared rod; ``--start``: the planner's start, as in ``rod-deploy plan``) with the declared rod; a residual the declared rod does not explain is tested against candidate
effects (a natural curvature, a wrong L_gb, too little friction), each fitted with the simulator as the forward
model and kept only on strong statistical evidence confirmed by a simulation (see
``rod_deploy.deployment.correction``). Writes DIR/report.json (parameters, effects_added with name, parameters,
evidence, error_before, error_after; warnings), DIR/correction.png (prescribed vs deployed, before and after),
DIR/rod_fitted.yaml; with ``--replan`` DIR/traj_corrected.csv planned with the fitted rod, and with ``--simulate``
its deployment predicted by the fitted simulator (error_after.e_mean_cm); a fitted natural curvature or friction,
which the planner does not model, is pre-compensated only with ``--simulate`` (the planner given a modified pattern,
the fitted simulator in the loop; report.replan.precompensation). Prints one summary line. The simulation
settings must be those that produced a simulated deployment (defaults: those of ``rod-deploy simulate``); each
simulation of a 0.9 m rod takes 10-40 s here, and the loop runs 1 (nothing to explain) to 1 + (number of
effects) + 4 (confirmations) + 2 (replanning) + 4 (pre-compensation) simulations.
"""
from __future__ import annotations

import json
from pathlib import Path

from rod_deploy.cli.main import CliError


def register(subparsers):
    p = subparsers.add_parser('correct', help='closed loop: explain a deployed shape (natural curvature, L_gb, '
                                              'friction), fit it, replan', description=__doc__.split('\n\n')[0])
    p.add_argument('--pattern', required=True, help='the prescribed pattern (points file x y [z], metres)')
    p.add_argument('--rod', required=True, help='the declared rod description YAML')
    p.add_argument('--deployed', required=True, help='deployed shape CSV (x,y), simulated or perceived')
    p.add_argument('--traj', help='the trajectory that laid it (default: planned with nn for the declared rod)')
    p.add_argument('--out', required=True, help='output directory (report.json, correction.png, ...)')
    p.add_argument('--replan', action='store_true', help='write DIR/traj_corrected.csv planned with the fitted rod')
    p.add_argument('--simulate', action='store_true',
                   help='with --replan: predict the corrected deployment with the fitted simulator (e_mean after)')
    p.add_argument('--effects', default='natural_curvature,L_gb,friction',
                   help='candidate effects, comma-separated (default: natural_curvature,L_gb,friction)')
    p.add_argument('--noise-floor-mm', type=float, default=0.5,
                   help='shapes closer than this are not told apart (perception, settings) [mm] (default 0.5)')
    p.add_argument('--friction', type=float, default=None,
                   help='Coulomb coefficient of the deployment (default: the rod file\'s, else 0.5)')
    p.add_argument('--edge-length', type=float, default=0.005, help='rod discretisation [m] (default 0.005)')
    p.add_argument('--dt', type=float, default=0.02, help='time step [s] (default 0.02, as simulate)')
    p.add_argument('--speed', type=float, default=0.01, help='gripper speed of the replay [m/s] (default 0.01)')
    p.add_argument('--start', choices=('tangent', 'achievable'), default=None,
                   help="the planner's start for the trajectory planned here (as in `rod-deploy plan`; default: the "
                        "planner's, achievable)")
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    p.set_defaults(func=run)


def _write_rod_yaml(path, rod):
    import yaml
    d = {'length': rod.length_m, 'radius': rod.radius_m, 'L_gb': rod.gravito_bending_length_m,
         'natural_curvature': rod.natural_curvature_per_m}
    if rod.friction is not None:
        d['friction'] = rod.friction
    if rod.density_kg_m3:
        d['density'] = rod.density_kg_m3
    if rod.name:
        d['name'] = rod.name
    Path(path).write_text(yaml.safe_dump({k: float(v) if k != 'name' else v for k, v in d.items()},
                                         sort_keys=False))


def run(args) -> int:
    import numpy as np

    from rod_deploy.deployment.correction import CorrectionError, CorrectionSettings, Deployment, correct
    from rod_deploy.deployment.metrics import read_deployed_csv, write_deployed_csv
    from rod_deploy.deployment.simulate import SimulationSettings
    from rod_deploy.planning.pattern_input import load_pattern
    from rod_deploy.planning.rod_description import load_rod_description
    from rod_deploy.planning.trajectory_io import read_trajectory_csv, write_trajectory_csv

    for name in ('edge_length', 'dt', 'speed', 'noise_floor_mm'):
        v = getattr(args, name)
        if not (np.isfinite(v) and v > 0):
            raise CliError(f'--{name.replace("_", "-")} must be positive, got {v}')
    if args.friction is not None and not (np.isfinite(args.friction) and args.friction > 0):
        raise CliError(f'--friction must be > 0, got {args.friction}')
    if args.simulate and not args.replan:
        raise CliError('--simulate simulates the corrected trajectory: give --replan too')
    effects = tuple(e.strip() for e in args.effects.split(',') if e.strip())
    settings = CorrectionSettings(effects=effects, noise_floor_m=args.noise_floor_mm * 1e-3)
    try:
        settings.validate()
        rod = load_rod_description(args.rod)
        pattern = load_pattern(args.pattern)
        observed = read_deployed_csv(args.deployed)
        deployment = None
        if args.traj:
            t, p, q = read_trajectory_csv(args.traj)
            deployment = Deployment(t, p, q, tuple(pattern[0]))
    except ValueError as e:
        raise CliError(str(e)) from None
    if args.friction is not None:
        import dataclasses
        rod = dataclasses.replace(rod, friction=args.friction)
    sim = SimulationSettings(edge_length_m=args.edge_length, dt_s=args.dt, max_gripper_speed_m_s=args.speed,
                             contact_tolerance_m=5e-4)   # a free end curled up by 0.1 mm still counts
    from rod_deploy.cli.progress import simulations_progress
    try:
        from rod_deploy.planning.trajectory import PlannerSettings
        planner = PlannerSettings(**({'start': args.start} if args.start else {}))
        with simulations_progress(args.quiet) as progress:
            report, diag, rp = correct(pattern, rod, observed, deployment, planner_settings=planner,
                                       sim_settings=sim, settings=settings, replan_trajectory=args.replan,
                                       simulate=args.simulate, progress=progress)
    except ValueError as e:
        raise CliError(str(e)) from None
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    files = {'report': str(out / 'report.json'), 'plot': str(out / 'correction.png'),
             'rod_fitted': str(out / 'rod_fitted.yaml')}
    _write_rod_yaml(out / 'rod_fitted.yaml', diag.rod)
    if rp is not None:
        write_trajectory_csv(out / 'traj_corrected.csv', rp.t, rp.position, rp.quaternion)
        files['trajectory'] = str(out / 'traj_corrected.csv')
        if rp.predicted_xy is not None:
            write_deployed_csv(out / 'deployed_predicted.csv', rp.predicted_xy)
            files['deployed_predicted'] = str(out / 'deployed_predicted.csv')
    from rod_deploy.deployment.plots import plot_correction
    plot_correction(out / 'correction.png', pattern, diag, rp, report)
    report['files'] = files
    report['inputs'] = {'pattern': args.pattern, 'rod': args.rod, 'deployed': args.deployed, 'traj': args.traj}
    (out / 'report.json').write_text(json.dumps(report, indent=2))
    added = ', '.join(f'{e["key"]} = {e["parameters"][e["key"]]:.4g}' for e in report['effects_added']) or 'none'
    after = report['error_after']
    print(f'rod-deploy correct: effects added: {added}; e_mean {report["error_before"]["e_mean_cm"]:.3f} cm -> '
          + (f'{after["e_mean_cm"]:.3f} cm (predicted)' if after and after['source'].startswith('the corrected')
             else 'unchanged (trajectory kept)' if after and rp is not None and not rp.replanned
             else 'unchanged (no effect)' if after else 'not simulated (use --replan --simulate)')
          + f'; residual {report["error_before"]["residual_rms_mm"]:.2f} mm RMS; {report["simulations"]} '
            f'simulations, {report["wall_time_s"]:.0f} s; {files["report"]}')
    return 0
