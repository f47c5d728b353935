"""`rod-deploy` command line: one subcommand per module in this package.

Each subcommand module exposes ``register(subparsers)``, which adds its parser and sets
``func`` (a callable taking the parsed arguments and returning an exit code).
"""
import argparse
import importlib
import sys

SUBCOMMAND_MODULES = ('grasp', 'perceive', 'plan', 'simulate', 'evaluate', 'correct')


class CliError(Exception):
    """A user-facing error: printed as one line, exit code 2."""


def build_parser():
    parser = argparse.ArgumentParser(
        prog='rod-deploy',
        description='Rod deployment tools: optimal grasp, pattern perception, trajectory planning, deployment '
                    'simulation and its Eq. 17 error.')
    sub = parser.add_subparsers(dest='command', required=True)
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(f'rod_deploy.cli.{name}').register(sub)
    return parser


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except CliError as exc:
        print(f'rod-deploy {args.command}: error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    # run as `python -m rod_deploy.cli.main`: this file is then loaded a second time as __main__, and the subcommands
    # raise the package module's CliError, not this copy's: call the package module's main
    from rod_deploy.cli.main import main as package_main
    sys.exit(package_main())
