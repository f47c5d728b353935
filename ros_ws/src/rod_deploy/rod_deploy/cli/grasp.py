"""`rod-deploy grasp`: the optimal grasp for one (ls_bar, kappa_bar, ks_bar) as JSON.

    rod-deploy grasp --ls 13.68 --kappa 0 --ks 2087
    {"position": [2.5663, 0.0, 12.1824], "rotvec": [0.0, -1.5708, 0.0], "force_residual": 0.0, "stable": true,
     "time_s": 0.07}

position: gripper relative to the connective node in units of L_gb, in the published local frame (x along the
pattern tangent, y = z_hat x tangent, z up); rotvec: axis-angle of R = m(ls) m(0)^T (Eq. 7).
kappa_bar follows the released code's sign: positive turns towards -y and puts the gripper at y < 0.
"""
import json
import math

import numpy as np

from .main import CliError

METHODS = {
    'numeric': 'bvp',   # the suspended part as one Kirchhoff-rod BVP (default, fast, mesh converged)
    'bvp': 'bvp',
    'alg2': 'alg2',     # paper Alg. 2-3: Newton on the gripper position over the forward BVP
    'der': 'der',       # Alg. 2-3 on a discrete elastic rod, as the released C++ solver (slow)
}


def register(subparsers):
    p = subparsers.add_parser(
        'grasp', help='optimal grasp for (ls_bar, kappa_bar, ks_bar) as JSON',
        description='Optimal gripper pose for deploying a rod (paper Sec. 3.2.3-4.2). Prints JSON with '
                    'position (units of L_gb, local frame: x tangent, y = z x tangent, z up), rotvec, '
                    'force_residual, stable, time_s.')
    p.add_argument('--ls', type=float, required=True, metavar='LS_BAR', help='suspended length / L_gb (> 0)')
    p.add_argument('--kappa', type=float, default=0.0, metavar='KAPPA_BAR',
                   help='pattern curvature x L_gb at the connective node (released sign convention; default 0)')
    p.add_argument('--ks', type=float, required=True, metavar='KS_BAR',
                   help='normalised stretching stiffness 4 L_gb^2 / h^2 (> 0; "inf" for an inextensible rod)')
    p.add_argument('--method', choices=sorted(METHODS), default='numeric',
                   help='numeric (= bvp, default): boundary value problem; alg2: paper Alg. 2-3 on the BVP; '
                        'der: Alg. 2-3 on a discrete elastic rod like the released solver (seconds)')
    p.add_argument('--convention', choices=('continuum', 'released'), default='continuum',
                   help='continuum (default): relative to the lift-off point, mesh converged; released: '
                        'relative to the released solver\'s second clamped node (one edge of 13.68/232 L_gb '
                        'further), which reproduces its published numbers')
    p.add_argument('--no-stability', action='store_true', help='skip the elastic-stability check ("stable": null)')
    p.add_argument('--details', action='store_true',
                   help='add inputs, method, clamp force and the stability diagnostics to the JSON')
    p.set_defaults(func=run)


#: the solver is checked up to here (benchmarks and tests); beyond it the shooting may overflow
TESTED_LS_MAX = 200.0
TESTED_KAPPA_MAX = 4.0


def run(args):
    from ..planning.optimal_grasp import RELEASED_CONNECTIVE_OFFSET, optimal_grasp
    from ..planning.suspended_rod import BVPError

    ls, kappa, ks = args.ls, args.kappa, args.ks
    if not (math.isfinite(ls) and ls > 0):
        raise CliError(f'--ls must be a positive number, got {ls}')
    if not math.isfinite(kappa):
        raise CliError(f'--kappa must be finite, got {kappa}')
    if math.isnan(ks) or ks <= 0:
        raise CliError(f'--ks must be positive, got {ks}')
    offset = RELEASED_CONNECTIVE_OFFSET if args.convention == 'released' else 0.0
    try:
        with np.errstate(all='ignore'):     # a shot that overflows is a failed trial, reported below if none works
            g = optimal_grasp(ls, kappa, ks, method=METHODS[args.method], check_stability=not args.no_stability,
                              connective_offset=offset)
    except BVPError as exc:
        hint = ''
        if ls > TESTED_LS_MAX or abs(kappa) > TESTED_KAPPA_MAX:
            hint = (f' (checked range: ls_bar up to {TESTED_LS_MAX:g}, |kappa_bar| up to {TESTED_KAPPA_MAX:g}; the '
                    f'training dataset covers ls_bar 0.5-100, kappa_bar 0-4)')
        raise CliError(f'no optimal grasp found for ls={ls}, kappa={kappa}, ks={ks}: {exc}{hint}') from exc
    out = g.as_dict()
    if args.details:
        out.update({'inputs': {'ls_bar': ls, 'kappa_bar': kappa, 'ks_bar': ks if math.isfinite(ks) else 'inf'},
                    'method': args.method, 'convention': args.convention,
                    'clamp_force': [float(v) for v in g.clamp_force],
                    'stability': _jsonable(g.stability)})
    print(json.dumps(out))
    return 0


def _jsonable(d):
    if d is None:
        return None
    return {k: (float(v) if isinstance(v, float) else v) for k, v in d.items()}
