"""Two replays of one trajectory (``replay_probe.py`` outputs, e.g. our DER and PyElastica, or one simulator at two
settings) compared over time at equal material coordinate: where and when the two rods part.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/replay_probe.py --sim der --pattern letterU \
        --method nn --out /tmp/U_der.npz
    PYTHONPATH=ros_ws/src/rod_deploy .venv-bench/bin/python benchmarks/replay_probe.py --sim elastica \
        --pattern letterU --method nn --out /tmp/U_el.npz
    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/probe_compare.py /tmp/U_der.npz /tmp/U_el.npz \
        --labels DER PyElastica [--every 5] [--out NAME.md] [--commit-results]

Both rods are sampled at the material coordinate s (arc length of the unstretched rod from the free end; node i of a
rod of N edges at s = i L / N) on the coarser rod's nodes, the finer one linearly interpolated. Per snapshot time
(replay time, 0 = the gripper leaves the hanging pose; each snapshot of the first file paired with the second's
nearest, within 0.05 s): the free end's position in each, the largest and mean distance between the two rods over the part lying on the table in both (centreline within
0.5 mm of the contact height) and over the whole rod, and where along s the largest one is. At the end: the error
profile of each (``error_profile.profile``: the error at touch-down against the pattern, and the motion on the table
after touch-down) per stretch of the pattern, side by side. With the normal forces ``replay_probe.py`` records: the
normal force that bounds friction summed over the touch-down zone, and how high the laid rod lies.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from error_profile import profile  # noqa: E402
from results_dir import add_results_argument, results_path  # noqa: E402


def at_material(nodes, s_query, length_m):
    """(k, 3) positions at material coordinates ``s_query`` of a rod with nodes (n, 3) evenly spaced in s."""
    s_nodes = np.linspace(0.0, length_m, nodes.shape[0])
    return np.column_stack([np.interp(s_query, s_nodes, nodes[:, k]) for k in range(3)])


def touchdown_normal(d, i_nodes, t, radius_m, length_m, before_m=0.025, after_m=0.015):
    """(normal force [N] the friction law bounds friction by, summed over the nodes within ``before_m`` before and
    ``after_m`` after the lift-off node (the first above ``LAID_HEIGHT_TOLERANCE_M``), the nodes' own weight there is
    not subtracted; mean height above the contact height of the laid nodes before that zone [m]) at the recorded
    normal-force snapshot nearest ``t``; nan when the file has none."""
    from rod_deploy.deployment.simulate import LAID_HEIGHT_TOLERANCE_M
    if 'normal_times' not in d.files:
        return float('nan'), float('nan')
    k = int(np.argmin(abs(d['normal_times'] - t)))
    z = d['nodes'][i_nodes][:, 2]
    s = np.linspace(0.0, length_m, len(z))
    lift = int(np.argmax(z > radius_m + LAID_HEIGHT_TOLERANCE_M))
    eps = 1e-9
    zone = (s > s[lift] - before_m - eps) & (s < s[lift] + after_m + eps)
    laid = (s < s[lift] - before_m - eps)
    return float(d['normal_law'][k][zone].sum()), float((z[laid] - radius_m).mean()) if laid.any() else float('nan')


def compare(npz_a, npz_b, radius_m, length_m, tol_m=5e-4):
    """Rows (t, free end a, free end b, max / mean distance on the laid part, where the max is [m of s], max on the
    whole rod) for every snapshot time common to both files."""
    a, b = np.load(npz_a, allow_pickle=True), np.load(npz_b, allow_pickle=True)
    ta, tb = a['times'], b['times']
    # snapshot times of the two files paired to the nearest (an explicit simulator's snapshots fall within a step of
    # the period's multiples, not on them)
    pairs = [(i, int(np.argmin(abs(tb - t)))) for i, t in enumerate(ta)]
    pairs = [(i, j) for i, j in pairs if abs(tb[j] - ta[i]) < 0.05]
    n = min(a['nodes'].shape[1], b['nodes'].shape[1])
    s = np.linspace(0.0, length_m, n)
    rows = []
    for i, j in pairs:
        t = ta[i]
        na = at_material(a['nodes'][i], s, length_m)
        nb = at_material(b['nodes'][j], s, length_m)
        d = np.linalg.norm(na - nb, axis=1)
        laid = (na[:, 2] <= radius_m + tol_m) & (nb[:, 2] <= radius_m + tol_m)
        laid &= np.cumprod(laid).astype(bool)                     # the laid stretch from the free end
        rows.append(dict(t=float(t), end_a=na[0, :2].copy(), end_b=nb[0, :2].copy(),
                         laid_m=float(s[laid][-1]) if laid.any() else 0.0,
                         max_laid=float(d[laid].max()) if laid.any() else float('nan'),
                         mean_laid=float(d[laid].mean()) if laid.any() else float('nan'),
                         s_max_laid=float(s[laid][np.argmax(d[laid])]) if laid.any() else float('nan'),
                         max_all=float(d.max()), s_max_all=float(s[np.argmax(d)]),
                         n_td=(touchdown_normal(a, i, t, radius_m, length_m)[0],
                               touchdown_normal(b, j, t, radius_m, length_m)[0]),
                         hover=(touchdown_normal(a, i, t, radius_m, length_m)[1],
                                touchdown_normal(b, j, t, radius_m, length_m)[1]),
                         at_s=(na, nb, s)))
    return rows, float(a['t_release_s']), float(b['t_release_s'])


def xy_at(row, s_m):
    """'(x, y) / (x, y)' in mm of both rods at material coordinate s_m."""
    na, nb, s = row['at_s']
    pa = [np.interp(s_m, s, na[:, k]) for k in range(2)]
    pb = [np.interp(s_m, s, nb[:, k]) for k in range(2)]
    return f'({1e3 * pa[0]:.1f}, {1e3 * pa[1]:.1f}) / ({1e3 * pb[0]:.1f}, {1e3 * pb[1]:.1f})'


def main():
    from deployment_table import RODS
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('npz', nargs=2, help='replay_probe.py outputs of the same trajectory')
    ap.add_argument('--labels', nargs=2, default=['a', 'b'])
    ap.add_argument('--rod', type=int, default=3)
    ap.add_argument('--every', type=float, default=5.0, help='table rows every this many simulated seconds')
    ap.add_argument('--stretch-cm', type=float, default=10.0)
    ap.add_argument('--at-s', type=float, default=0.09, help='material coordinate [m] whose x, y the table lists')
    ap.add_argument('--out', default='probe_compare.md', help='results file name (in the results folder)')
    add_results_argument(ap)
    args = ap.parse_args()
    rod = RODS[args.rod]
    rows, rel_a, rel_b = compare(args.npz[0], args.npz[1], rod['radius'], rod['length'])
    la, lb = args.labels
    pa, pb = (profile(f, rod['radius'], rod['L_gb']) for f in args.npz)
    profiles = len(pa['s']) > 1 and len(pb['s']) > 1 and pa['laid'].any() and pb['laid'].any()
    lines = [f'# {la} against {lb}, `benchmarks/probe_compare.py`', '',
             f'Files: `{args.npz[0]}` ({la}), `{args.npz[1]}` ({lb}); rod #{args.rod}. e_mean (Eq. 17): {la} '
             f'{pa["e_mean_cm"]:.3f} cm, {lb} {pb["e_mean_cm"]:.3f} cm. Release of the free end at replay time '
             f'{rel_a:.1f} s / {rel_b:.1f} s. Distances between the two rods at equal material coordinate s (from the '
             'free end); "laid": the stretch from the free end lying on the table in both.', '',
             f'"N at touch-down": the normal force that bounds friction (`replay_probe.py`\'s normal_law), summed over '
             'the nodes from 2.5 cm before to 1.5 cm after each rod\'s lift-off node, in mN (the weight of 4 cm of '
             f'rod #{args.rod}: {1e3 * 0.04 * 1180 * np.pi * rod["radius"] ** 2 * 9.81:.2f} mN); "laid height": the '
             'mean height of the laid nodes before that zone above the contact height, um.', '',
             f'| t s | free end {la} mm | free end {lb} mm | laid in both cm | max dist. laid mm (at s cm) | '
             'mean dist. laid mm | max dist. whole rod mm (at s cm) | N at touch-down mN | laid height um | '
             f'x, y at s = {100 * args.at_s:g} cm mm |', '|---|---|---|---|---|---|---|---|---|---|']
    last_t = -np.inf
    for i, r in enumerate(rows):
        if r['t'] - last_t < args.every - 1e-9 and i != len(rows) - 1:
            continue
        last_t = r['t']
        lines.append(f"| {r['t']:.1f} | ({1e3 * r['end_a'][0]:.1f}, {1e3 * r['end_a'][1]:.1f}) | "
                     f"({1e3 * r['end_b'][0]:.1f}, {1e3 * r['end_b'][1]:.1f}) | {100 * r['laid_m']:.0f} | "
                     f"{1e3 * r['max_laid']:.2f} ({100 * r['s_max_laid']:.0f}) | {1e3 * r['mean_laid']:.2f} | "
                     f"{1e3 * r['max_all']:.2f} ({100 * r['s_max_all']:.0f}) | "
                     f"{1e3 * r['n_td'][0]:.1f} / {1e3 * r['n_td'][1]:.1f} | "
                     f"{1e6 * r['hover'][0]:.1f} / {1e6 * r['hover'][1]:.1f} | {xy_at(r, args.at_s)} |")
    text = '\n'.join(lines) + '\n'
    if profiles:
        text += profile_table(pa, pb, la, lb, args.stretch_cm)
    print(text)
    out = results_path(args, args.out)
    out.write_text(text)
    print(f'results: {out}')


def profile_table(pa, pb, la, lb, stretch_cm):
    lines = ['', f'Error profile per stretch of the pattern (`error_profile.py`; mm): final error, error at '
              f'touch-down, motion on the table after touch-down.', '',
              f'| s cm | final {la} | final {lb} | touch-down {la} | touch-down {lb} | moved after {la} | '
              f'moved after {lb} |', '|---|---|---|---|---|---|---|']
    edges = np.arange(0.0, min(pa['s'][-1], pb['s'][-1]) + 1e-9, stretch_cm / 100)
    for lo, hi in zip(edges, np.append(edges[1:], np.inf)):
        ma = (pa['s'] >= lo) & (pa['s'] < hi)
        mb = (pb['s'] >= lo) & (pb['s'] < hi)
        if not (ma.any() and mb.any()):
            continue
        lines.append(f"| {100 * lo:.0f}-{100 * min(hi, pa['s'][-1]):.0f} | {1e3 * pa['err_final'][ma].mean():.2f} | "
                     f"{1e3 * pb['err_final'][mb].mean():.2f} | {1e3 * pa['err_touch'][ma].mean():.2f} | "
                     f"{1e3 * pb['err_touch'][mb].mean():.2f} | {1e3 * pa['moved'][ma].mean():.2f} | "
                     f"{1e3 * pb['moved'][mb].mean():.2f} |")
    lines.append(f"| all | {1e3 * pa['err_final'].mean():.2f} | {1e3 * pb['err_final'].mean():.2f} | "
                 f"{1e3 * pa['err_touch'].mean():.2f} | {1e3 * pb['err_touch'].mean():.2f} | "
                 f"{1e3 * pa['moved'].mean():.2f} | {1e3 * pb['moved'].mean():.2f} |")
    return '\n'.join(lines) + '\n'


if __name__ == '__main__':
    main()
