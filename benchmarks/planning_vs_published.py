"""Our Alg. 4 trajectories against the published planner's for the paper's 7 patterns, with the difference split
into its causes.

    python benchmarks/planning_vs_published.py [--methods nn,numeric] [--step-mm 1] [--commit-results]

Reads ``../shared/reference/rod_deployment`` in place (the published patterns, their preprocessed nodes, per-node
network inputs/outputs and trajectories; GPL: compared with, never copied). Rod: the one the published outputs were
made for (h = 2 mm, L_gb = 0.034 m, 0.89 m suspended at the start, k_s_bar = 1156).

For each pattern and each of our methods, the gripper position gap [mm] between the published trajectory and ours
at the same arc length s of the pattern (ours planned every ``--step-mm`` and interpolated linearly in s), split as:

* ``grasp model``: our grasps (network, or the numeric solver with continuation) at the published per-node inputs,
  placed with the published nodes and tangents (recovered exactly from the published trajectory and network
  outputs), against the published trajectory: only the grasp differs (their network, trained on the released
  discrete solver's convention, vs our continuum optimum);
* ``pattern processing``: the rest, end to end minus that: their smoothing spline (s = 0.001 m^2 on the sum of
  squared residuals, i.e. about 2.5 mm RMS from the points, tangent and curvature by finite differences of
  non-uniform nodes) vs ours (0.5 mm RMS, uniform arc length, analytic derivatives of the spline).

Also: the per-node inputs (ls_bar the same formula, (L - s) / L_gb; kappa_bar after each smoothing), the angle
between the rod's exit directions (+z_gripper), the full orientation difference once the constant rotation about
the rod (the planner's choice, CONTRACTS.md section 4) is taken out, and quaternion sign flips
between neighbouring poses (the published files have some; ours none). Writes a markdown table, JSON and a plot.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from results_dir import add_results_argument, results_path
from rod_deploy.planning.neural_controller import load_grasp_network
from rod_deploy.planning.optimal_grasp import grasp_sequence
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import GRIPPER_IN_GRASP_FRAME, PlannerSettings, local_frames, plan_trajectory

REF = Path(os.environ.get('ROD_DEPLOYMENT_REFERENCE',
                          Path(__file__).resolve().parents[2] / 'shared' / 'reference' / 'rod_deployment'))
PATTERNS = ('line', 'circle', 'sine', 'letterU', 'letterC', 'letterL', 'letterA')
ROD = {'length': 0.89, 'radius': 0.002, 'L_gb': 0.034}
#: the published planner's smoothing spline: s = 0.001 m^2 (sum of squared residuals), i.e. sqrt(s / n) RMS
PUBLISHED_SPLINE_S_M2 = 0.001


def load_published(ref, name):
    """The published pattern, nodes, per-node inputs/outputs and trajectory, with the node tangents and the
    signed kappa_bar (our released sign: > 0 turns right) recovered from them."""
    out = ref / 'reference_outputs'
    io = np.loadtxt(out / f'{name}_nn_io.txt')
    nodes = np.loadtxt(out / f'{name}_pattern_preprocessed.txt')[:, :2]
    traj = np.loadtxt(out / f'{name}_traj_NN.txt')
    raw = np.loadtxt(ref / 'patterns' / f'{name}.txt')[:, :2]
    # turning direction of the published nodes (the network saw |kappa_bar| and y was mirrored for left turns)
    d = np.diff(nodes, axis=0)
    cross = d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]
    left = np.concatenate([[cross[0]], cross, [cross[-1]]]) > 0
    y_bar = np.where(left, -io[:, 4], io[:, 4])
    # the published tangent at each node, exactly: the angle of the horizontal offset gripper - node minus the angle
    # of the local offset (x_bar, y_bar)
    off = traj[:, :2] - nodes
    heading = np.arctan2(off[:, 1], off[:, 0]) - np.arctan2(y_bar, io[:, 3])
    tangent = np.column_stack([np.cos(heading), np.sin(heading)])
    kappa_signed = np.where(left, -1.0, 1.0) * io[:, 2]
    s = (ROD['length'] - io[:, 0] * ROD['L_gb'])
    return dict(io=io, nodes=nodes, traj=traj, raw=raw, tangent=tangent, left=left, s=s,
                inputs=np.column_stack([io[:, 0], io[:, 1], kappa_signed]))


def place(nodes, tangent, q_bar, rotvec):
    """Alg. 4's q_M = q_C + R_t q_bar L_gb and the contract's gripper frame, at given nodes and tangents."""
    Rt = local_frames(tangent)
    pos = np.column_stack([nodes, np.zeros(len(nodes))]) + np.einsum('nij,nj->ni', Rt, q_bar) * ROD['L_gb']
    R = Rt @ Rotation.from_rotvec(rotvec).as_matrix() @ GRIPPER_IN_GRASP_FRAME
    return pos, R


def orientation_gaps_deg(R_ours, R_pub):
    """(angle between the rod exit directions z_gripper, full angle once the constant rotation about the rod, the
    mean over the poses of R_ours^T R_pub, is taken out), degrees per pose."""
    z = np.degrees(np.arccos(np.clip(np.sum(R_ours[:, :, 2] * R_pub[:, :, 2], axis=1), -1.0, 1.0)))
    align = Rotation.from_matrix(np.einsum('nji,njk->nik', R_ours, R_pub)).mean().as_matrix()
    full = Rotation.from_matrix(np.einsum('nji,njk->nik', R_ours @ align, R_pub)).magnitude()
    return z, np.degrees(full)


def interp_rows(s_new, s, values):
    return np.stack([np.interp(s_new, s, values[:, j]) for j in range(values.shape[1])], axis=1)


def stats(x):
    return {'mean': float(np.mean(x)), 'median': float(np.median(x)), 'max': float(np.max(x))}


def compare(name, pub, method, smoothing, step_m, net):
    rod = rod_description_from_dict(ROD)
    settings = PlannerSettings(method=method, step_m=step_m)
    if smoothing == 'published':
        settings.smoothing_m = float(np.sqrt(PUBLISHED_SPLINE_S_M2 / len(pub['raw'])))
    t0 = time.perf_counter()
    plan = plan_trajectory(pub['raw'], rod, settings)
    plan_s = time.perf_counter() - t0
    k = plan.first_grasp_index
    R_pub = Rotation.from_quat(pub['traj'][:, 3:7]).as_matrix()
    s = np.clip(pub['s'], 0.0, plan.pattern.length)
    # end to end: ours at the published nodes' arc length
    ours_pos = interp_rows(s, plan.pattern.s, plan.position[k:])
    ours_R = Slerp(plan.pattern.s, plan.rotation[k:])(s).as_matrix()
    e2e_mm = np.linalg.norm(ours_pos - pub['traj'][:, :3], axis=1) * 1e3
    z_deg, full_deg = orientation_gaps_deg(ours_R, R_pub)
    # grasp model only: our grasps at their inputs, nodes and tangents
    if method == 'nn':
        q_bar, rotvec = net.predict(pub['inputs'][:, 0], pub['inputs'][:, 1], pub['inputs'][:, 2])
    else:
        seq = grasp_sequence(pub['inputs'])
        q_bar, rotvec = np.array([g.position for g in seq]), np.array([g.rotvec for g in seq])
    g_pos, g_R = place(pub['nodes'], pub['tangent'], q_bar, rotvec)
    grasp_mm = np.linalg.norm(g_pos - pub['traj'][:, :3], axis=1) * 1e3
    g_z_deg, g_full_deg = orientation_gaps_deg(g_R, R_pub)
    # the grasp orientations themselves, in the local frame (theirs mirrored back for left turns)
    rv_pub = pub['io'][:, 6:9].copy()
    rv_pub[pub['left']] *= [-1.0, 1.0, -1.0]
    local_deg = np.degrees((Rotation.from_rotvec(rotvec).inv() * Rotation.from_rotvec(rv_pub)).magnitude())
    # the published file against its own network outputs: quaternion = R*_i R*_0^T diag(1, -1, -1), with
    # R* = R_t R (Alg. 4), i.e. orientations relative to the first grasp
    Rs = local_frames(pub['tangent']) @ Rotation.from_rotvec(rv_pub).as_matrix()
    self_R = np.einsum('nij,kj->nik', Rs, Rs[0]) @ np.diag([1.0, -1.0, -1.0])
    self_deg = np.degrees(Rotation.from_matrix(np.einsum('nji,njk->nik', self_R, R_pub)).magnitude())
    # check of the recovered published tangents (and so of the turning directions): against finite differences
    fd = np.gradient(pub['nodes'], axis=0)
    fd /= np.linalg.norm(fd, axis=1)[:, None]
    tangent_deg = np.degrees(np.arccos(np.clip(np.sum(fd * pub['tangent'], axis=1), -1.0, 1.0)))
    # pattern processing: nodes and curvature
    node_mm = np.linalg.norm(interp_rows(s, plan.pattern.s, plan.pattern.xy) - pub['nodes'], axis=1) * 1e3
    kappa_ours = np.interp(s, plan.pattern.s, plan.inputs[:, 2])
    inside = pub['s'] <= plan.pattern.length            # (the two smoothed lengths differ by about a millimetre)
    ls_ours = np.interp(s[inside], plan.pattern.s, plan.inputs[:, 0])
    return {
        'pattern': name, 'method': method, 'smoothing': smoothing, 'smoothing_m': settings.smoothing_m, 'nodes_published': int(len(s)), 'nodes_ours': int(len(plan.pattern.s)),
        'pattern_length_m': {'published': float(pub['s'][-1]), 'ours': plan.pattern.length},
        'plan_time_s': plan_s,
        'gripper_gap_mm': stats(e2e_mm),
        'gripper_gap_grasp_model_mm': stats(grasp_mm),
        'published_tangent_check_deg': stats(tangent_deg),
        'node_gap_mm': stats(node_mm),
        'kappa_bar_gap': stats(np.abs(kappa_ours - pub['inputs'][:, 2])),
        'ls_bar_gap': stats(np.abs(ls_ours - pub['io'][inside, 0])),
        'exit_direction_gap_deg': stats(z_deg),
        'orientation_gap_deg': stats(full_deg),
        'exit_direction_gap_grasp_model_deg': stats(g_z_deg),
        'orientation_gap_grasp_model_deg': stats(g_full_deg),
        'grasp_orientation_gap_local_deg': stats(local_deg),
        'published_self_consistency_deg': stats(self_deg),
        'quaternion_sign_flips': {'published': int(np.sum(np.sum(pub['traj'][1:, 3:7] * pub['traj'][:-1, 3:7],
                                                                  axis=1) < 0)),
                                  'ours': int(np.sum(np.sum(plan.quaternion[1:] * plan.quaternion[:-1], axis=1) < 0))},
        '_curves': {'s': s, 'e2e_mm': e2e_mm, 'grasp_mm': grasp_mm, 'ours_xy': plan.position[k:, :2],
                    'pattern_xy': plan.pattern.xy},
    }


def plot(rows, pubs, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    names = list(pubs)
    fig, axes = plt.subplots(2, len(names), figsize=(3.2 * len(names), 6.4))
    for j, name in enumerate(names):
        ax, bx = axes[0, j], axes[1, j]
        pub = pubs[name]
        ax.plot(*pub['raw'].T, 'k-', lw=2.5, alpha=0.3, label='pattern')
        ax.plot(*pub['traj'][:, :2].T, 'k--', lw=1, label='published gripper')
        for r in rows:
            if r['pattern'] != name or r['smoothing'] != 'ours':
                continue
            c = r['_curves']
            ax.plot(*c['ours_xy'].T, lw=1, label=f'ours {r["method"]}')
            bx.plot(c['s'], c['e2e_mm'], lw=1, label=f'{r["method"]}: end to end')
            bx.plot(c['s'], c['grasp_mm'], lw=1, ls=':', label=f'{r["method"]}: grasp model only')
        ax.set_aspect('equal', adjustable='datalim')
        ax.set_title(name)
        ax.set_xlabel('x [m]')
        bx.set_xlabel('pattern arc length s [m]')
        if j == 0:
            ax.set_ylabel('y [m]')
            bx.set_ylabel('gripper position gap to published [mm]')
    axes[0, 0].legend(fontsize=7)
    axes[1, 0].legend(fontsize=7)
    fig.suptitle('Our Alg. 4 trajectories vs the published planner (rod h = 2 mm, L_gb = 3.4 cm, L = 0.89 m)')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--methods', default='nn,numeric', help='comma-separated: nn, numeric')
    ap.add_argument('--step-mm', type=float, default=1.0, help='our node step for the comparison [mm]')
    ap.add_argument('--reference', type=Path, default=REF, help='the published reference folder (read in place)')
    add_results_argument(ap)
    args = ap.parse_args()
    methods = [m.strip() for m in args.methods.split(',') if m.strip()]
    if not set(methods) <= {'nn', 'numeric'} or not methods:
        ap.error(f'--methods: nn and/or numeric, got {args.methods!r}')
    if not (args.reference / 'reference_outputs').is_dir():
        print(f'planning_vs_published: error: {args.reference} has no reference_outputs/ (the published outputs '
              f'are read in place)', file=sys.stderr)
        sys.exit(2)
    from tqdm import tqdm
    net = load_grasp_network()
    pubs = {name: load_published(args.reference, name) for name in PATTERNS}
    cases = [(n, m, sm) for sm in ('ours', 'published') for m in methods for n in PATTERNS]
    rows = [compare(name, pubs[name], method, smoothing, args.step_mm * 1e-3, net)
            for name, method, smoothing in tqdm(cases, desc='patterns x methods x smoothing')]

    lines = [
        '# Our Alg. 4 trajectories vs the published planner (7 patterns)',
        '',
        f'`python benchmarks/planning_vs_published.py --methods {",".join(methods)} --step-mm {args.step_mm:g}` on '
        f'{platform.machine()} ({os.cpu_count()} CPUs, shared; times are noisy). Rod: h = 2 mm, L_gb = 0.034 m, '
        f'L = 0.89 m (k_s_bar = 1156), the one the published outputs were made for. Gaps are between the published '
        f'gripper pose and ours at the same pattern arc length s (mean / max over the published nodes). '
        f'Smoothing "ours": the planner default ({PlannerSettings().smoothing_m * 1e3:g} mm RMS from the points); '
        f'"published": the released planner\'s spline s = {PUBLISHED_SPLINE_S_M2:g} m^2, i.e. '
        f'sqrt(s / n) = 2.3-3.2 mm RMS for these patterns. "grasp model": our grasps at the published per-node inputs, '
        f'nodes and tangents (independent of the smoothing).',
        '',
        '| pattern | method | smoothing | gripper gap mm | grasp model mm | grasp model orientation deg | published self-consistency deg | '
        'node gap mm | '
        'abs kappa_bar gap | '
        'exit direction gap deg | orientation gap deg | quaternion flips published / ours | plan s |',
        '|---|---|---|---|---|---|---|---|---|---|---|---|---|',
    ]
    for r in rows:
        g, gm, n, kb = (r[k] for k in ('gripper_gap_mm', 'gripper_gap_grasp_model_mm', 'node_gap_mm', 'kappa_bar_gap'))
        zd, od, fl = r['exit_direction_gap_deg'], r['orientation_gap_deg'], r['quaternion_sign_flips']
        go, sc = r['grasp_orientation_gap_local_deg'], r['published_self_consistency_deg']
        lines.append(f'| {r["pattern"]} | {r["method"]} | {r["smoothing"]} | {g["mean"]:.2f} / {g["max"]:.2f} | '
                     f'{gm["mean"]:.2f} / {gm["max"]:.2f} | {go["mean"]:.2f} / {go["max"]:.2f} | '
                     f'{sc["mean"]:.2f} / {sc["max"]:.2f} | '
                     f'{n["mean"]:.2f} / {n["max"]:.2f} | '
                     f'{kb["mean"]:.3f} / {kb["max"]:.3f} | {zd["mean"]:.2f} / {zd["max"]:.2f} | '
                     f'{od["mean"]:.2f} / {od["max"]:.2f} | {fl["published"]} / {fl["ours"]} | '
                     f'{r["plan_time_s"]:.2f} |')
    for sm in ('ours', 'published'):
        for m in methods:
            sel = [r for r in rows if r['method'] == m and r['smoothing'] == sm]
            lines.append(f'| **all** | {m} | {sm} | {np.mean([r["gripper_gap_mm"]["mean"] for r in sel]):.2f} / '
                         f'{max(r["gripper_gap_mm"]["max"] for r in sel):.2f} | '
                         f'{np.mean([r["gripper_gap_grasp_model_mm"]["mean"] for r in sel]):.2f} / '
                         f'{max(r["gripper_gap_grasp_model_mm"]["max"] for r in sel):.2f} | | | | | | | | |')
    tcheck = [r['published_tangent_check_deg'] for r in rows]
    ls_gap = max(r['ls_bar_gap']['max'] for r in rows)
    lines += [
        '',
        f'Per-node ls_bar: the published planner\'s formula and ours are the same, (L - s) / L_gb with s the arc '
        f'length of the smoothed pattern (largest difference at the same s: {ls_gap:.1e}). The published tangents '
        f'recovered from its trajectory and network outputs agree with finite differences of its nodes to '
        f'{max(t["median"] for t in tcheck):.2f} deg (median; worst node {max(t["max"] for t in tcheck):.1f} deg, '
        f'at the pattern ends where one-sided differences are crude).',
        '',
        '"grasp model orientation": our grasp rotation against theirs in the local frame (theirs mirrored back for '
        'left turns). "published self-consistency": the published quaternion against R*_i R*_0^T diag(1, -1, -1) '
        'built from its own network outputs (R* = R_t R of Alg. 4): the published orientations are relative to the '
        'first grasp, which is set to (1, 0, 0, 0); where this column is large the published file departs from its '
        'own network outputs, so the orientation gaps there are not ours.',
        '',
    ]
    md = results_path(args, 'planning_vs_published.md')
    md.write_text('\n'.join(lines) + '\n')
    js = results_path(args, 'planning_vs_published.json')
    js.write_text(json.dumps([{k: v for k, v in r.items() if k != '_curves'} for r in rows], indent=1) + '\n')
    png = results_path(args, 'planning_vs_published.png')
    plot(rows, pubs, png)
    print('\n'.join(lines))
    print(f'wrote {md}, {js}, {png}')


if __name__ == '__main__':
    main()
