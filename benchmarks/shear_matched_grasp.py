"""Shear-matched grasps (issue #10): can the grasp apply the lateral force the laid rod needs at the connective node?

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/shear_matched_grasp.py [--commit-results]

The laid rod at rest with the planned curvature kappa(s) carries the moment EI kappa and the lateral shear
n_perp = -EI kappa' (m_z' = -n_perp): the grasp that applies exactly that at q_C leaves friction only EI kappa''.
The paper's optimal grasp (moment-free gripper, n0_x = 0) applies n0_y as an output instead. This script measures,
on the suspended-rod BVP (``planning.suspended_rod``, kind ``shear``; ``optimal_grasp.shear_matched_grasp``):

1. the moment-free grasp's n0_y per kappa_bar and the moment balance about the vertical through q_C,
   kappa_bar_bvp - m_z(ls) = x_g n0_y - y_g n0_x (an identity of the continuum; its residual checks the solver);
2. the gripper releases (a clamp supplying a bending moment out of / in the lift-off plane, n0_x = 0 kept): how far
   from the moment-free value n0_y can be moved by continuation (steps halved down to 1e-4), per ls_bar, the gripper
   moment that needs and the stability of the reached grasp (DER second variation, gripper clamped);
3. the tangential release (gripper moment free, n0_x released): the n0_x that n0_y = 0 (a laid circle's shear) needs,
   and |d n0_x / d n0_y| near the moment-free grasp as kappa_bar -> 0.

Units: lengths L_gb, forces EI / L_gb^2, moments EI / L_gb; n0 the force of the suspended part on the laid part,
frame x along the pattern tangent, y = z x x, z up; kappa_bar in the released sign (kappa_bar > 0 turns right,
m_z(0) = -kappa_bar).
"""
from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from results_dir import add_results_argument, results_path
from rod_deploy.planning.optimal_grasp import elastic_stability, optimal_grasp, shear_matched_grasp
from rod_deploy.planning.suspended_rod import BVPError, solve_suspended_rod

LS = (25.0, 12.0, 8.0, 5.0, 3.0, 1.5)


def moment_balance_residual(sol):
    """|kappa_bvp - m_z(ls) - (x_g n0_y - y_g n0_x)|."""
    n0, q = sol.Y[0, 9:12], sol.gripper_position
    return abs(sol.Y[0, 8] - sol.Y[-1, 8] - (q[0] * n0[1] - q[1] * n0[0]))


def continue_to(free_sol, kb, release, target, min_step=1e-4, max_step=0.02):
    """Continuation in n0_y from the moment-free solution towards ``target``: (last solution, n0_y reached)."""
    cur, f, step = free_sol, float(free_sol.Y[0, 10]), max_step
    while f != target:
        nxt = f + np.clip(target - f, -step, step)
        try:
            cur = solve_suspended_rod('shear', free_sol.ls_bar, np.inf, kb, guess=cur, s=cur.s, lateral_force=nxt,
                                      shear_release=release)
            f = nxt
            step = min(2 * step, max_step)
        except BVPError:
            step /= 2
            if step < min_step:
                break
    return cur, f


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    add_results_argument(ap)
    args = ap.parse_args()
    c0 = time.process_time()
    lines = ['# Shear-matched grasps: can the grasp supply the laid rod\'s shear? '
             '`python benchmarks/shear_matched_grasp.py`',
             '', f'Machine: {platform.machine()}, {os.cpu_count()} cores (shared, load {os.getloadavg()[0]:.1f}). '
             'Inextensible rod; BVP of `planning/suspended_rod.py` (kind `shear`), units L_gb, EI / L_gb^2, EI / L_gb. '
             'n0: force of the suspended part on the laid part at q_C (x tangent, y = z x x); kappa_bar in the '
             'released sign (m_z(0) = -kappa_bar).', '',
             '## 1. The moment-free (paper) grasp', '',
             '| ls_bar | kappa_bar | n0_y | n0_y / kappa_bar | gripper x_g, y_g | t(ls)_z | moment balance residual |',
             '|---|---|---|---|---|---|---|']
    free = {}
    for ls in LS:
        for kap in (0.25, 0.5, 1.0):
            g = optimal_grasp(ls, kap, np.inf, check_stability=False)
            free[ls, kap] = g
            s = g.solution
            lines.append(f'| {ls:g} | {kap:g} | {s.Y[0, 10]:+.4f} | {s.Y[0, 10] / kap:+.3f} | '
                         f'{s.gripper_position[0]:.3f}, {s.gripper_position[1]:.3f} | {s.t[-1, 2]:.3f} | '
                         f'{moment_balance_residual(s):.1e} |')
    lines += ['', 'The laid rod needs n0_y = d kappa_bar / d(s / L_gb) (zero on a circle); the moment-free grasp '
              'applies about -kappa_bar / 2.3 whatever the curve does next. With n0_x = 0 and a moment-free gripper '
              'the balance about the vertical reads kappa = x_g n0_y: the lateral force is the pattern\'s moment over '
              'the gripper\'s lead.', '',
              '## 2. Gripper releases: n0_y moved by a gripper moment (n0_x = 0), kappa_bar 0.5', '',
              'Continuation from the moment-free n0_y towards each target (steps <= 0.02, halved down to 1e-4 on '
              'failure); "reached" is the last n0_y solved. |m(ls)|: the gripper moment; m_z(ls): its component about '
              'the vertical; stable: DER second variation with the gripper clamped (position, direction, twist).', '',
              '| release | ls_bar | n0_y free | target | reached | |m(ls)| | m_z(ls) | t(ls)_z | stable |',
              '|---|---|---|---|---|---|---|---|---|']
    kap = 0.5
    for release in ('gripper_out_of_plane', 'gripper_in_plane'):
        for ls in LS:
            s0 = free[ls, kap].solution
            n_free = float(s0.Y[0, 10])
            for target in (0.5 * n_free, 0.0, -n_free):
                sol, reached = continue_to(s0, s0.kappa_bar, release, target)
                stable = elastic_stability(sol, gripper='clamp')['stable'] if reached == target else '-'
                lines.append(f'| {release} | {ls:g} | {n_free:+.4f} | {target:+.4f} | {reached:+.4f} | '
                             f'{np.linalg.norm(sol.m[-1]):.3f} | {sol.m[-1, 2]:+.3f} | {sol.t[-1, 2]:.3f} | {stable} |')
                print(lines[-1], flush=True)
                if reached != target:
                    break
    lines += ['', '## 3. Tangential release: n0_y moved by a force along the tangent (gripper moment free)', '',
              'n0_x for the laid circle\'s n0_y = 0, and the slope |d n0_x / d n0_y| for a step of 0.005 from the '
              'moment-free grasp (central difference), ls_bar 12; stable: DER second variation, gripper by position. '
              '|n0_h|: the horizontal force the laid rod then takes (moment free: |n0_y|).', '',
              '| kappa_bar | n0_y free | n0_x at n0_y = 0 | |n0_h| matched / free | slope dn0_x/dn0_y | stable |',
              '|---|---|---|---|---|---|']
    for kap in (1.0, 0.5, 0.25, 0.1, 0.02):
        g = optimal_grasp(12.0, kap, np.inf, check_stability=False)
        n_free = float(g.solution.Y[0, 10])
        slope = []
        for d in (0.005, -0.005):
            try:
                gs, _ = shear_matched_grasp(12.0, kap, np.inf, n_free + d, release='tangential', moment_free=g)
                slope.append(gs.solution.Y[0, 9])
            except BVPError:
                slope.append(np.nan)
        sl = abs(slope[0] - slope[1]) / 0.01
        try:
            gm, _ = shear_matched_grasp(12.0, kap, np.inf, 0.0, release='tangential', moment_free=g,
                                        check_stability=True)
            nx = float(gm.solution.Y[0, 9])
            row = f'{nx:+.4f} | {abs(nx):.3f} / {abs(n_free):.3f} | {sl:.2f} | {gm.stable}'
        except BVPError as exc:
            row = f'failed ({str(exc)[:60]}) | - | {sl:.2f} | -'
        lines.append(f'| {kap:g} | {n_free:+.4f} | {row} |')
        print(lines[-1], flush=True)
    lines += ['', '## 4. The smallest horizontal force along the tangential family (gripper moment free), ls_bar 12',
              '',
              'On a laid circle the rod needs no horizontal force at q_C (n0_y = -kappa\' = 0, n0_x = 0): whatever '
              'friction must absorb there is |n0_h|. The family n0_y -> (n0_x, n0_y) is scanned from the moment-free '
              'grasp towards n0_y = 0 (20 steps) and its smallest |n0_h| reported, with the floor |kappa| / |r_g| '
              '(the balance kappa = x_g n0_y - y_g n0_x with n0_h along (x_g, -y_g), r_g the gripper\'s horizontal '
              'offset at that grasp).', '',
              '| kappa_bar | |n0_h| moment free | smallest |n0_h| on the family | at n0_y | n0_x | '
              'kappa / |r_g| there |',
              '|---|---|---|---|---|---|']
    for kap in (0.25, 0.5, 1.0, 2.0):
        g = optimal_grasp(12.0, kap, np.inf, check_stability=False)
        n_free = float(g.solution.Y[0, 10])
        best, cur = (abs(n_free), n_free, 0.0, kap / np.hypot(*g.solution.gripper_position[:2])), g.solution
        for f in np.linspace(n_free, 0.0, 21)[1:]:
            try:
                cur = solve_suspended_rod('shear', 12.0, np.inf, g.solution.kappa_bar, guess=cur, s=cur.s,
                                          lateral_force=f, shear_release='tangential')
            except BVPError:
                break
            nh = float(np.hypot(cur.Y[0, 9], cur.Y[0, 10]))
            if nh < best[0]:
                best = (nh, f, float(cur.Y[0, 9]), kap / np.hypot(*cur.gripper_position[:2]))
        lines.append(f'| {kap:g} | {abs(n_free):.4f} | {best[0]:.4f} | {best[1]:+.4f} | {best[2]:+.4f} | '
                     f'{best[3]:.4f} |')
        print(lines[-1], flush=True)
    lines += ['', f'CPU time: {time.process_time() - c0:.0f} s.']
    out = results_path(args, 'shear_matched_grasp.md')
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))
    print(f'results: {out}')


if __name__ == '__main__':
    main()
