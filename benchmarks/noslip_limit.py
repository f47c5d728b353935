"""The no-slip limit of a deployment (issue #10: which simulator is right on a curve): replays of one trajectory at
rising friction (``replay_probe.py --friction MU``, nodes every 0.5 s) read node by node.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/noslip_limit.py LABEL=FILE.npz ... [--rod 3]
        [--out NAME.md] [--commit-results]

A known answer: when friction is high enough that a node on the table never moves, the laid shape IS the locus of
the touch-down points (``moved after`` -> 0), and where a node touches down is set by the suspended rod's statics
for the gripper pose of that moment (``suspended_statics.py`` checks both simulators' against the BVP the planner
solved). Per replay: Eq. 17's e_mean; over the curved part (|kappa_bar| > 0.1) the mean signed offset of the laid
rod from the pattern along the pattern's normal at equal arc length (+ = outside the bend), at the end and at
touch-down, and the mean motion on the table after touch-down (``error_profile.profile``); the same per stretch.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def signed_outside(xy, Ps, P, s_nodes):
    """Offset of xy from Ps along the pattern's normal, + towards the outside of the bend there [m]."""
    sp = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    th = np.unwrap(np.arctan2(np.gradient(P[:, 1]), np.gradient(P[:, 0])))
    kap = np.gradient(th, sp)
    w = max(1, int(round(0.01 / np.mean(np.diff(sp)))))
    kap = np.convolve(kap, np.ones(w) / w, mode='same')
    thn = np.interp(s_nodes, sp, th)
    left = np.column_stack([-np.sin(thn), np.cos(thn)])
    inward = np.sign(np.interp(s_nodes, sp, kap))[:, None] * left
    return -np.sum((xy - Ps) * inward, axis=1)


def summarise(npz, radius_m, lgb_m):
    from error_profile import profile
    p = profile(npz, radius_m, lgb_m)
    d = np.load(npz, allow_pickle=True)
    nodes = d['nodes']
    n = len(p['s'])
    first = np.array([np.argmin(np.abs(d['times'] - t)) for t in p['times']])
    touch = nodes[first, np.arange(n), :2]
    out_final = signed_outside(p['final'][:n, :2], p['Ps'], p['pattern'], p['s'])
    out_touch = signed_outside(touch, p['Ps'], p['pattern'], p['s'])
    curved = (p['kbar'] > 0.1) & p['laid']
    return dict(p=p, out_final=out_final, out_touch=out_touch, curved=curved,
                cpu=float(d['cpu_s']) if 'cpu_s' in d else float('nan'))


def main():
    from deployment_table import RODS
    from results_dir import add_results_argument, results_path
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('runs', nargs='+', help='LABEL=replay_probe.npz')
    ap.add_argument('--rod', type=int, default=3)
    ap.add_argument('--stretch-cm', type=float, default=10.0)
    ap.add_argument('--title', default='')
    ap.add_argument('--out', default='noslip_limit.md')
    ap.add_argument('--plot', default=None, metavar='NAME.png', help='also plot the final offset along the pattern')
    add_results_argument(ap)
    args = ap.parse_args()
    rod = RODS[args.rod]
    runs = [r.split('=', 1) for r in args.runs]
    res = [(lab, summarise(f, rod['radius'], rod['L_gb'])) for lab, f in runs]
    lines = [f'# The no-slip limit, `benchmarks/noslip_limit.py` {args.title}', '',
             'Offsets in mm, + outside the bend (signed, along the pattern normal at equal arc length), means over '
             'the curved part (|kappa_bar| > 0.1); "moved": motion on the table after touch-down (touch-down: the '
             'first 0.5 s snapshot from which the node stays within 0.5 mm of the table).', '',
             '| run | e_mean cm | offset at end | offset at touch-down | moved after touch-down | largest moved | '
             'CPU s |', '|---|---|---|---|---|---|---|']
    for lab, r in res:
        c, p = r['curved'], r['p']
        lines.append(f"| {lab} | {p['e_mean_cm']:.3f} | {1e3 * r['out_final'][c].mean():+.2f} | "
                     f"{1e3 * r['out_touch'][c].mean():+.2f} | {1e3 * p['moved'][c].mean():.2f} | "
                     f"{1e3 * p['moved'][p['laid']].max():.2f} | {r['cpu']:.0f} |")
    lines += ['', f'Per {args.stretch_cm:g} cm of the pattern: offset at the end / at touch-down (mm, + outside).', '']
    s_end = min(r['p']['s'][-1] for _, r in res)
    edges = np.arange(0.0, s_end, args.stretch_cm / 100)
    lines.append('| s cm | ' + ' | '.join(lab for lab, _ in res) + ' |')
    lines.append('|---|' + '---|' * len(res))
    for a in edges:
        b = a + args.stretch_cm / 100
        cells = []
        for _, r in res:
            m = (r['p']['s'] >= a) & (r['p']['s'] < b) & r['p']['laid']
            cells.append(f"{1e3 * r['out_final'][m].mean():+.2f} / {1e3 * r['out_touch'][m].mean():+.2f}"
                         if m.any() else '-')
        lines.append(f'| {100 * a:.0f}-{100 * b:.0f} | ' + ' | '.join(cells) + ' |')
    text = '\n'.join(lines) + '\n'
    print(text)
    out = results_path(args, args.out)
    out.write_text(text)
    print(f'wrote {out}')
    if args.plot:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(10, 3.6))
        colours = plt.cm.tab20(np.arange(len(res)) % 20)
        for (lab, r), c in zip(res, colours):
            m = r['p']['laid'] & (r['p']['kbar'] > 0.05)          # where the pattern bends ("outside" defined)
            y = np.where(m, 1e3 * r['out_final'], np.nan)
            ax.plot(100 * r['p']['s'], y, lw=1.2, color=c, label=f"{lab} ({r['p']['e_mean_cm']:.3f} cm)")
        ax.axhline(0.0, color='0.5', lw=0.8)
        ax.set_xlabel('arc length from the free end [cm]')
        ax.set_ylabel('offset [mm], + outside')
        ax.set_title(f'laid rod against the pattern {args.title}; where |kappa_bar| > 0.05', fontsize=9)
        ax.legend(fontsize=6, loc='center left', bbox_to_anchor=(1.01, 0.5))
        fig.tight_layout()
        png = results_path(args, args.plot)
        fig.savefig(png, dpi=90)
        print(f'wrote {png}')


if __name__ == '__main__':
    main()
