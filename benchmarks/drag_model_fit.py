"""Fit of the drag compensation's terms (``rod_deploy.planning.bend_drag``) to the templates the refinement
converged to (``benchmarks/drag_residual.py --save-dir DIR``), node by node.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/drag_model_fit.py [--dir out/drag_residual] \
        [--commit-results]

Target: the offset (left normal of the drawn pattern, m) of what the refined plan was planned for, from the free
end's taper on (the planner compensates from the free end on since the twelfth round; ``--beyond-start``: only
beyond the friction-limited start and its taper, the eleventh round's rule). Terms (``bend_drag.drag_terms``,
each per unit gain, m): the drag at the touch-down point (L_gb x the smoothed excess) and the translation of the rest
of the curve by the drag (the excess integrated along the inward normal, leaking over a length ell; the template
moved against it). Least squares of the gains per ell, and per case the RMS of target - model for the one-constant
model (DRAG_GAIN) and the fitted one, leave-one-case-out as well.
"""
from __future__ import annotations

import argparse
import glob
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402


def load(directory):
    cases = []
    for f in sorted(glob.glob(str(Path(directory) / '*.npz'))):
        o = dict(np.load(f, allow_pickle=True))
        o['file'] = Path(f).stem
        cases.append(o)
    return cases


def design(o, ell_m, taper_m, cols=(0, 1), beyond_start=False):
    from rod_deploy.planning.bend_drag import drag_terms
    tangent = np.column_stack([o['normal'][:, 1], -o['normal'][:, 0]])
    start_m = float(o['start_m']) if beyond_start else 0.0
    terms = drag_terms(o['s'], tangent, o['kappa_bar'], float(o['Lgb']), float(o['mu']), shift_m=ell_m,
                       start_m=start_m)
    X = np.column_stack([np.sum(terms[k] * o['normal'], axis=1) for k in cols])
    keep = o['s'] >= start_m + taper_m
    return X[keep], o['off_refined'][keep]


def main():
    from rod_deploy.planning.bend_drag import DRAG_GAIN, START_TAPER_M
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--dir', default='out/drag_residual')
    ap.add_argument('--ells', default='0.1,0.2,0.4,inf', help='leak lengths of the shift term [m]')
    ap.add_argument('--terms', default='drag,shift', help='the terms fitted (drag, shift or both)')
    ap.add_argument('--beyond-start', action='store_true',
                    help='offsets and target only beyond the friction-limited start (the eleventh round\'s rule)')
    ap.add_argument('--cases', default=None, help='comma-separated case names (files without .npz); default all')
    ap.add_argument('--out-name', default='drag_model_fit.md')
    add_results_argument(ap)
    args = ap.parse_args()
    cases = load(args.dir)
    if args.cases:
        cases = [c for c in cases if c['file'] in args.cases.split(',')]
    cols = [('drag', 'shift').index(t) for t in args.terms.split(',')]
    lines = ['# Fit of the drag compensation\'s terms to the refined templates, `python benchmarks/drag_model_fit.py`',
             '', f'{len(cases)} cases: ' + ', '.join(c['file'] for c in cases) + '. Terms: drag (L_gb x smoothed '
             'excess), shift (the translation by the drag, the excess along the inward normal integrated with a leak '
             'length ell, projected on the normal). RMS of refined - model over the nodes ' +
             ('beyond the start and its taper' if args.beyond_start else 'from the free end\'s taper on') + ', mm.', '',
             f'| ell m | gains ({args.terms.replace(",", ", ")}) | pooled RMS mm | leave-one-out RMS mm |',
             '|---|---|---|---|']
    best = None
    for ell in (float(x) for x in args.ells.split(',')):
        XY = [design(c, ell, START_TAPER_M, cols, args.beyond_start) for c in cases]
        X = np.vstack([a for a, _ in XY])
        y = np.concatenate([b for _, b in XY])
        g = np.linalg.lstsq(X, y, rcond=None)[0]
        rms = float(np.sqrt(np.mean((y - X @ g) ** 2)))
        loo = []
        for k in range(len(cases)):
            Xk = np.vstack([a for i, (a, _) in enumerate(XY) if i != k])
            yk = np.concatenate([b for i, (_, b) in enumerate(XY) if i != k])
            gk = np.linalg.lstsq(Xk, yk, rcond=None)[0]
            loo.append(XY[k][1] - XY[k][0] @ gk)
        loo = float(np.sqrt(np.mean(np.concatenate(loo) ** 2)))
        lines.append(f'| {ell:g} | {", ".join(f"{v:.3f}" for v in g)} | {1e3 * rms:.2f} | {1e3 * loo:.2f} |')
        print(lines[-1], flush=True)
        if best is None or loo < best[0]:
            best = (loo, ell, g, XY)
    loo, ell, g, XY = best
    lines += ['', f'Best ell {ell:g} m (leave-one-out). Per case, RMS mm of the refined template against: '
              f'zero, the one-constant model (drag gain {DRAG_GAIN:g}), the fitted terms.', '',
              '| case | e_mean default -> refined cm | zero | one-constant | fitted |', '|---|---|---|---|---|']
    for c, (X, y) in zip(cases, XY):
        r = lambda v: 1e3 * float(np.sqrt(np.mean(v ** 2)))
        lines.append(f'| {c["file"]} | {float(c["e0"]):.3f} -> {float(c["e1"]):.3f} | {r(y):.2f} | '
                     f'{r(y - DRAG_GAIN * design(c, ell, START_TAPER_M, (0,), args.beyond_start)[0][:, 0]):.2f} | '
                     f'{r(y - X @ g):.2f} |')
    out = results_path(args, args.out_name)
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines[-len(cases) - 2:]))
    print(f'results: {out}')


if __name__ == '__main__':
    main()
