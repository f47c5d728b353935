"""flex-ident: command-line identification of a flexible object's stiffness from a recorded bag.

    flex-ident identify --bag BAG --experiment EXP.yaml --out DIR [--method lm|lbfgsb|steepest]
                        [--cost end_effector|joint_angles] [--max-iterations N] [--no-continuation] [--no-plots]
                        [--no-diagnose] [--validation-fraction F] [--quiet]
    flex-ident request  --bag BAG --experiment EXP.yaml [--out DIR] [--timeout S]   (to a running
                        stiffness_identifier node: prints its report)

The closed loop is on by default (--no-diagnose: the declared parameters only). Loop recordings: after k_theta,
k_phi are identified, the residual is screened for the effects the declared model lacks (loop joint damping, arm
viscous and Coulomb friction shared or per joint, torque sensor bias and gain, measurement delay, the object's
rest-angle offset); each statistically significant one (BIC on the time-correlated residual) is added, identified
jointly with the declared parameters and listed in the report's effects_added; every model along the way is also
refitted without the last --validation-fraction of the window and measured there ("validation"); a final residual
far above the noise the data shows is reported as a wrong model structure (warnings). Arm-only experiments (no
object) run the torque-domain loop (always).

Writes DIR/report.json (CONTRACTS.md section 3) and plots, shows a progress bar (tqdm, on stderr) and prints the
identified parameters. On bad input it prints one line ``flex-ident: error: ...`` and exits with status 2, writing
no report.
"""
from __future__ import annotations

import argparse
import json
import sys

EXIT_BAD_INPUT = 2


class _Parser(argparse.ArgumentParser):
    """argparse with the project's one-line error format (``flex-ident: error: ...``, exit status 2)."""

    def error(self, message):
        self.exit(EXIT_BAD_INPUT, f'flex-ident: error: {message} (see flex-ident {self._subcommand()}--help)\n')

    def _subcommand(self):
        parts = self.prog.split()
        return (parts[1] + ' ') if len(parts) > 1 else ''


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog='flex-ident', description=__doc__.split('\n\n')[0])
    sub = parser.add_subparsers(dest='command', required=True, parser_class=_Parser)
    p = sub.add_parser('identify', help='identify the experiment\'s parameters from a recorded bag')
    p.add_argument('--bag', required=True, help='rosbag2 directory (MCAP or sqlite3) with /joint_states')
    p.add_argument('--experiment', required=True, help='experiment YAML (CONTRACTS.md section 2)')
    p.add_argument('--out', required=True, help='output directory for report.json and the plots')
    p.add_argument('--method', default='lm',
                   help='lm (Levenberg-Marquardt, default), lbfgsb (L-BFGS-B with the adjoint gradient) or '
                        'steepest (the paper\'s projected steepest descent with Armijo steps)')
    p.add_argument('--cost', choices=['end_effector', 'joint_angles'], default=None,
                   help='tracking cost (default: the experiment\'s, else end_effector as in the paper)')
    p.add_argument('--max-iterations', type=int, default=None, help='optimizer iteration limit')
    p.add_argument('--no-continuation', action='store_true',
                   help='optimize on the whole recording at once (default: warm start on its first 2.5, 5, 10 ... s, '
                        'which keeps soft loops and wide motions out of local minima)')
    p.add_argument('--no-diagnose', dest='diagnose', action='store_false', default=True,
                   help='identify the declared parameters only (default: after identification, find, add and '
                        'jointly identify the effects the declared model lacks; report: effects_added)')
    p.add_argument('--diagnose', dest='diagnose', action='store_true',
                   help='the default, accepted for compatibility')
    p.add_argument('--validation-fraction', type=float, default=0.3,
                   help='the last part of the window kept out of every fit (default 0.3). Arm-only experiments: it '
                        'decides which effects to add; loop recordings: each model along the closed loop is refitted '
                        'without it and its error there is reported under "validation"')
    p.add_argument('--no-plots', action='store_true', help='write report.json only')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    from flex_ident.cli.request import register
    register(sub)
    return parser


class _ProgressBar:
    """tqdm bar over the optimizer iterations with the current cost and parameters, on stderr.

    Created when optimization starts (input errors found while loading never leave a bar behind) and only on a
    terminal (tqdm's ``disable=None``), so that captured stderr holds nothing but errors.
    """

    def __init__(self, total: int, enabled: bool):
        self.total = total
        self.enabled = enabled
        self.bar = None

    def __call__(self, info: dict):
        stage = info.get('stage', '')
        if self.bar is None:
            if not self.enabled or stage not in ('optimize', 'warm start'):
                return
            from tqdm import tqdm
            self.bar = tqdm(total=self.total, desc='optimize', unit='it', file=sys.stderr, dynamic_ncols=True,
                            disable=None, leave=True)
        self.bar.set_description(f'warm start on the first {info["window_s"]:g} s' if stage == 'warm start' else stage)
        if stage == 'warm start':
            self.bar.refresh()
        elif stage == 'optimize' and 'iteration' in info:
            self.bar.n = min(int(info['iteration']), self.bar.total)
            post = {}
            if 'cost' in info:
                post['cost'] = f'{info["cost"]:.3e}'
            for k, v in (info.get('parameters') or {}).items():
                post[k] = f'{v:.4g}'
            self.bar.set_postfix(post, refresh=False)
            self.bar.refresh()
        elif stage == 'done':
            self.bar.total = max(self.bar.n, 1)
            self.bar.refresh()

    def close(self):
        if self.bar is not None:
            self.bar.close()


def _kernels_cached() -> bool:
    """False when numba's on-disk cache of the model kernels is missing beside the package (the first call then
    compiles for about a minute); True when it exists or lives elsewhere (read-only install)."""
    import os
    from pathlib import Path
    mechanics = Path(__file__).resolve().parents[1] / 'mechanics'
    if not os.access(mechanics, os.W_OK):
        return True
    return any((mechanics / '__pycache__').glob('variational_integrator.*.nbi'))


def identify_command(args) -> int:
    from flex_ident.identification.identify import IdentificationSettings, identify
    from flex_ident.identification.optimizers import canonical_method

    method = canonical_method(args.method)
    if args.max_iterations is not None and args.max_iterations < 1:
        raise ValueError(f'--max-iterations must be positive, got {args.max_iterations}')
    total = args.max_iterations or (30 if method == 'lm' else 100)
    bar = _ProgressBar(total, enabled=not args.quiet)
    if not args.quiet and not _kernels_cached():
        print('flex-ident: first run on this machine: compiling the model kernels (about a minute, once)',
              file=sys.stderr, flush=True)
    try:
        run = identify(args.bag, args.experiment, args.out,
                       IdentificationSettings(method=method, cost=args.cost, max_iterations=args.max_iterations,
                                              continuation=not args.no_continuation,
                                              plots=not args.no_plots, diagnose=args.diagnose,
                                              validation_fraction=args.validation_fraction), progress=bar)
    finally:
        bar.close()
    report = run.report
    summary = {'parameters': report['parameters'], 'parameter_std': report['parameter_std'],
               'error_before': report['error_before'], 'error_after': report['error_after'],
               'effects_added': [{'name': e['name'], 'parameters': e['parameters']}
                                 for e in report.get('effects_added', [])],
               **({'warnings': report['warnings']} if report.get('warnings') else {}),
               'iterations': report['iterations'], 'wall_time_s': round(report['wall_time_s'], 2),
               'report': str((__import__('pathlib').Path(args.out) / 'report.json'))}
    print(json.dumps(summary, indent=2))
    for warning in report.get('warnings', []):
        print(f'flex-ident: warning: {warning}', file=sys.stderr)
    return 0


def main(argv=None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        if args.command == 'identify':
            return identify_command(args)
        if args.command == 'request':
            from flex_ident.cli.request import request_command
            return request_command(args)
    except ValueError as exc:          # every bad-input error of the project is a ValueError subclass
        message = ' '.join(str(exc).split())
        print(f'flex-ident: error: {message}', file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print('flex-ident: interrupted', file=sys.stderr)
        return 130
    return 1


if __name__ == '__main__':
    sys.exit(main())
