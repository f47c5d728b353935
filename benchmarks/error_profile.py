"""Where along a pattern the deployment error arises, and whether the rod was laid there wrong or moved after it
was laid: the nodes of a DER replay recorded every second (``replay_probe.py --sim der``) read node by node.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/replay_probe.py --sim der --pattern letterA \
        --method nn --out /tmp/A_nn.npz [--traj saved.csv]
    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/error_profile.py /tmp/A_nn.npz [/tmp/A_refined.npz] \
        --labels nn nn_refined --out benchmarks/results/error_profile_letterA.png [--commit-results]

For node i of the rod (arc length s_i = i x edge from the free end, the same pairing as Eq. 17 up to its
resampling): the final error |x_i(end) - P(s_i)|; the error at touch-down |x_i(t_i) - P(s_i)|, t_i the first
snapshot with the node on the table (centreline within 0.5 mm of z = radius) and staying there; and how far the node
moved on the table after it (|x_i(end) - x_i(t_i)|). Beside them the pattern's |kappa_bar| = |kappa| L_gb at s_i.
A large touch-down error is the planner's (or the grasp's); a large motion after touch-down is the laid rod dragged
by the suspended part (or creeping). Prints a summary per stretch of the pattern and writes a plot (and a markdown
table next to it).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402


def profile(npz, radius_m, lgb_m, tol_m=5e-4):
    d = np.load(npz, allow_pickle=True)
    nodes, P = d['nodes'], d['pattern'][:, :2]
    final = nodes[-1]
    edge = float(np.mean(np.linalg.norm(np.diff(final, axis=0), axis=1)))
    s_node = edge * np.arange(final.shape[0])
    sp = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    keep = s_node <= sp[-1]
    s_node = s_node[keep]
    Ps = np.column_stack([np.interp(s_node, sp, P[:, k]) for k in range(2)])
    on = nodes[:, :len(s_node), 2] <= radius_m + tol_m                     # (snapshots, nodes)
    # touch-down: the first snapshot from which the node stays on the table to the end
    stays = np.flip(np.cumprod(np.flip(on, axis=0), axis=0), axis=0).astype(bool)
    first = np.where(stays.any(axis=0), np.argmax(stays, axis=0), -1)
    laid = first >= 0
    idx = np.where(laid, first, nodes.shape[0] - 1)
    touch = nodes[idx, np.arange(len(s_node)), :2]
    err_final = np.linalg.norm(final[:len(s_node), :2] - Ps, axis=1)
    err_touch = np.linalg.norm(touch - Ps, axis=1)
    moved = np.linalg.norm(final[:len(s_node), :2] - touch, axis=1)
    # the shape alone: each node's distance to the nearest point of the pattern (a lag along it does not count)
    dense_s = np.linspace(0.0, sp[-1], 4000)
    dense = np.column_stack([np.interp(dense_s, sp, P[:, k]) for k in range(2)])
    nearest = np.array([np.min(np.linalg.norm(dense - x, axis=1)) for x in final[:len(s_node), :2]])
    # the pattern's curvature at s_i (finite differences of the tangent angle, smoothed over 1 cm)
    th = np.unwrap(np.arctan2(np.gradient(P[:, 1]), np.gradient(P[:, 0])))
    kap = np.gradient(th, sp)
    w = max(1, int(round(0.01 / np.mean(np.diff(sp)))))
    kap = np.convolve(kap, np.ones(w) / w, mode='same')
    kbar = np.abs(np.interp(s_node, sp, kap)) * lgb_m
    return dict(s=s_node, err_final=err_final, err_touch=err_touch, moved=moved, nearest=nearest, kbar=kbar, laid=laid,
                times=d['times'][idx], e_mean_cm=float(d['e_mean_cm']), pattern=P, final=final, Ps=Ps)


def main():
    from deployment_table import RODS
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('npz', nargs='+', help='replay_probe.py --sim der outputs')
    ap.add_argument('--labels', nargs='+')
    ap.add_argument('--rod', type=int, default=3)
    ap.add_argument('--out', default='error_profile.png', help='plot file name (in the results folder)')
    ap.add_argument('--stretch-cm', type=float, default=5.0, help='summary per stretch of this length')
    add_results_argument(ap)
    args = ap.parse_args()
    rod = RODS[args.rod]
    labels = args.labels or [Path(f).stem for f in args.npz]
    profs = [profile(f, rod['radius'], rod['L_gb']) for f in args.npz]
    out = results_path(args, Path(args.out).name)
    lines = [f'# Error profile along the pattern, `benchmarks/error_profile.py` ({", ".join(labels)})', '',
             'Per stretch of the pattern (arc length from the free end): mean final error (Eq. 17\'s pairing at equal '
             'arc length), mean distance to the nearest point of the pattern (the shape alone), mean error at '
             'touch-down, mean motion on the table after touch-down (mm), largest |kappa_bar| of the pattern there.',
             '']
    for lab, p in zip(labels, profs):
        lines += [f'## {lab}: e_mean (Eq. 17) {p["e_mean_cm"]:.3f} cm', '',
                  '| s cm | final mm | nearest mm | at touch-down mm | moved after mm | max abs kappa_bar |',
                  '|---|---|---|---|---|---|']
        edges = np.arange(0.0, p['s'][-1] + 1e-9, args.stretch_cm / 100)
        for a, b in zip(edges, np.append(edges[1:], p['s'][-1] + 1e-9)):
            m = (p['s'] >= a) & (p['s'] < b)
            if m.any():
                lines.append(f'| {100 * a:.0f}-{100 * b:.0f} | {1e3 * p["err_final"][m].mean():.2f} | '
                             f'{1e3 * p["nearest"][m].mean():.2f} | '
                             f'{1e3 * p["err_touch"][m].mean():.2f} | {1e3 * p["moved"][m].mean():.2f} | '
                             f'{p["kbar"][m].max():.2f} |')
        lines.append('')
    print('\n'.join(lines))
    out.with_suffix('.md').write_text('\n'.join(lines) + '\n')
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1 + len(profs), 1, figsize=(9, 3.2 * (1 + len(profs))))
    ax = axes[0]
    P = profs[0]['pattern']
    ax.plot(P[:, 0], P[:, 1], '-', color='0.6', lw=4, label='pattern')
    for lab, p, c in zip(labels, profs, ('tab:red', 'tab:blue', 'tab:green')):
        n = len(p['s'])
        ax.plot(p['final'][:n, 0], p['final'][:n, 1], '-', color=c, lw=1.2, label=f'{lab} (DER)')
    for sc in np.arange(0.0, profs[0]['s'][-1], 0.1):                      # arc-length ticks every 10 cm
        xy = profs[0]['Ps'][np.argmin(abs(profs[0]['s'] - sc))]
        ax.annotate(f'{100 * sc:.0f}', xy, fontsize=7, color='k')
    ax.set_aspect('equal', adjustable='datalim')
    ax.legend(fontsize=7)
    ax.set_title('top view; numbers: arc length from the free end [cm]', fontsize=9)
    for ax, lab, p in zip(axes[1:], labels, profs):
        ax.plot(100 * p['s'], 1e3 * p['err_final'], 'k-', label='final error')
        ax.plot(100 * p['s'], 1e3 * p['nearest'], 'k:', label='distance to the pattern (shape alone)')
        ax.plot(100 * p['s'], 1e3 * p['err_touch'], 'tab:orange', label='error at touch-down')
        ax.plot(100 * p['s'], 1e3 * p['moved'], 'tab:purple', ls='--', label='moved on the table after')
        ax.set_ylabel('mm')
        ax2 = ax.twinx()
        ax2.fill_between(100 * p['s'], 0, p['kbar'], color='tab:green', alpha=0.15)
        ax2.set_ylabel('pattern |kappa_bar| (shaded)', fontsize=8)
        ax.set_xlabel('arc length from the free end [cm]')
        ax.set_title(f'{lab}: e_mean {p["e_mean_cm"]:.3f} cm', fontsize=9)
        ax.legend(fontsize=7, loc='upper left')
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out, dpi=60)
    print(f'results: {out}')


if __name__ == '__main__':
    main()
