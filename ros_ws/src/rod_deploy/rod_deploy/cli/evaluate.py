"""`rod-deploy evaluate`: the paper's Eq. 17 between a pattern and a deployed shape; prints one JSON line.

    rod-deploy evaluate --pattern P --deployed deployed.csv [--n 50] [--directed]

P is a points file or an image with its mapping (as for ``rod-deploy plan``). Output: e_mean_cm, sigma_cm, e_max_cm,
pattern and deployed lengths [m], coverage (deployed / pattern length), and which direction was compared.
"""
from __future__ import annotations

import json
import sys

from rod_deploy.cli.main import CliError


def register(subparsers):
    p = subparsers.add_parser('evaluate', help='Eq. 17 error of a deployed shape against the pattern',
                              description=__doc__.split('\n\n')[0])
    p.add_argument('--pattern', required=True, help='pattern: points file (x y [z]) or image (with a mapping)')
    p.add_argument('--deployed', required=True, help='deployed shape CSV (x,y)')
    p.add_argument('--m-per-px', type=float, help='for an image pattern: table metres per pixel')
    p.add_argument('--origin', type=float, nargs=2, metavar=('ROW', 'COL'), help='origin pixel for --m-per-px')
    p.add_argument('--homography', help='for an image pattern: 3x3 homography file')
    p.add_argument('--n', type=int, default=50, help='points of the arc-length resampling (default 50, the paper)')
    p.add_argument('--directed', action='store_true',
                   help='compare in the given direction only (default: the better of both, a drawn stroke has none)')
    p.set_defaults(func=run)


def run(args) -> int:
    from rod_deploy.deployment.metrics import eq17_error, read_deployed_csv
    from rod_deploy.planning.pattern_input import load_pattern

    if args.n < 2:
        raise CliError(f'--n must be >= 2, got {args.n}')
    try:
        pattern = load_pattern(args.pattern, m_per_px=args.m_per_px, origin=args.origin, homography=args.homography)
        deployed = read_deployed_csv(args.deployed)
    except ValueError as e:
        raise CliError(str(e)) from None
    print(json.dumps(eq17_error(pattern, deployed, n=args.n, directed=args.directed)))
    from rod_deploy.planning.pattern_input import sparse_points_note
    from rod_deploy.planning.trajectory import process_pattern
    try:
        note = sparse_points_note(pattern, process_pattern(pattern).xy)
    except ValueError:                   # a pattern the planner could not take: nothing to compare with
        note = None
    if note:
        print(f'rod-deploy evaluate: note: {note}', file=sys.stderr)
    return 0
