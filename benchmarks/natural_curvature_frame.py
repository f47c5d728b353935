"""Which way does the laid rod's material frame lie? (the frame the simulator's natural curvature acts in)

The simulator maps a rod file's natural curvature k0 to the material rest curvature kappa2 = NATURAL_CURVATURE_SIGN
k0 (``rod_deploy.deployment.simulate``), which turns a laid rod left for k0 > 0 only if its director d1 points UP
on the table (kappa2 = -kb . d1; kb = +z |kappa| for a left turn). This script deploys a 0.3 m rod (L_gb 3.4 cm) in
our simulator with the planner's own trajectories (nn, its gripper roll) and reads, at the end, the material d1 of
the laid edges: its vertical component d1_z (first / last three laid edges: laid during the lead-in or just after,
and last), for straight and curved patterns turning left and right (the network's mirroring for negative
curvature), along +x and along -y, for the tangent and the friction-limited start, with and without a natural
curvature. Also the laid curve's turn beyond the pattern's (degrees over the laid length).

    .venv/bin/python benchmarks/natural_curvature_frame.py     # about 30 s; writes results/natural_curvature_frame.md
"""
import dataclasses
import sys
from pathlib import Path

import numpy as np

import rod_deploy.deployment.simulate as sim
from rod_deploy.deployment.metrics import eq17_error
from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment
from rod_deploy.physics.reference_frames import material_frames
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

_captured = {}


class _Capture(sim.DiscreteElasticRod):
    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        _captured['rod'] = self


sim.DiscreteElasticRod = _Capture            # keep the simulated rod to read its final material frame

ROD = rod_description_from_dict({'length': 0.3, 'radius': 0.002, 'L_gb': 0.034, 'friction': 0.5})
FAST = SimulationSettings(edge_length_m=0.01, dt_s=0.1, max_gripper_speed_m_s=0.03, contact_tolerance_m=5e-4)
_a = np.linspace(0.0, 0.07 / 0.08, 30)
HOOK = np.vstack([np.column_stack([np.linspace(0, 0.05, 11)[:-1], np.zeros(10)]),
                  np.column_stack([0.05 + 0.08 * np.sin(_a), 0.08 * (1 - np.cos(_a))])])   # 5 cm + 7 cm of R 8 cm
LINE = np.column_stack([np.linspace(0, 0.15, 31), np.zeros(31)])
PATTERNS = {'line +x': LINE, 'line -y': np.column_stack([LINE[:, 1], -LINE[:, 0]]),
            'hook left': HOOK, 'hook right (mirrored)': HOOK * [1, -1]}


def turn(xy):
    t = np.diff(xy, axis=0)
    a = np.unwrap(np.arctan2(t[:, 1], t[:, 0]))
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(t, axis=1))]), a


def main():
    rows = ['| start | pattern | k0 [1/m] | laid d1_z first 3 | last 3 | min | roll [deg] | d1 . left | '
            'extra turn [deg] | '
            'e_mean [cm] |', '|---|---|---|---|---|---|---|---|---|---|']
    for start in ('tangent', 'achievable'):
        for pname, P in PATTERNS.items():
            if start == 'achievable' and pname.startswith('line'):
                continue                                      # a straight start is left unchanged
            plan = plan_trajectory(P, ROD, PlannerSettings(start=start))
            for k0 in (0.0, 3.0, -3.0, 8.0):
                rod = dataclasses.replace(ROD, natural_curvature_per_m=k0)
                try:
                    res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod, FAST)
                except sim.DeploymentError as e:
                    rows.append(f'| {start} | {pname} | {k0:+g} | failed: {e} |')
                    continue
                r = _captured['rod']
                th = r.state.q[4 * np.arange(r.n_edges) + 3]
                m1, _ = material_frames(r.state.d1, r.state.d2, th)
                k = len(res.deployed_xy)
                if k < 5:
                    rows.append(f'| {start} | {pname} | {k0:+g} | only {k} nodes laid (the rod curls off the '
                                f'table) | | | | | |')
                    print(rows[-1], flush=True)
                    continue
                d1z = m1[:max(k - 1, 1), 2]
                tang = r.state.tangents[:max(k - 1, 1)]
                left = np.column_stack([-tang[:, 1], tang[:, 0], np.zeros(len(tang))])     # z x t
                side = float(np.mean(np.sum(m1[:max(k - 1, 1)] * left, axis=1)))
                e = eq17_error(P, res.deployed_xy, directed=True)['e_mean_cm'] if k >= 2 else float('nan')
                sd, ad = turn(res.deployed_xy)
                sp, ap = turn(P)
                L = 0.95 * min(sd[-1], sp[-1])
                extra = (np.interp(L, sd[1:], ad) - ad[0]) - (np.interp(L, sp[1:], ap) - ap[0])
                rows.append(f'| {start} | {pname} | {k0:+g} | {d1z[:3].mean():+.3f} | {d1z[-3:].mean():+.3f} | '
                            f'{d1z.min():+.3f} | {np.degrees(np.arccos(np.clip(d1z.mean(), -1, 1))):.0f} | '
                            f'{side:+.2f} | '
                            f'{np.degrees(extra):+.1f} | {e:.3f} |')
                print(rows[-1], flush=True)
    # an 'effective curvature' plan: the 15 cm line planned as an arc of curvature -k0 or +k0, laid by the k0 rod
    eff = ['| k0 [1/m] | planned curvature [1/m] | e_mean against the line [cm] |', '|---|---|---|']
    s = np.linspace(0.0, 0.15, 61)
    for k0 in (3.0, -3.0):
        rod = dataclasses.replace(ROD, natural_curvature_per_m=k0)
        for kp in (0.0, -k0, k0, -k0 / 3):
            arc = np.column_stack([np.sin(kp * s) / kp, (1 - np.cos(kp * s)) / kp]) if kp else LINE
            plan = plan_trajectory(arc, ROD)
            d = simulate_deployment(plan.t, plan.position, plan.quaternion, rod, FAST).deployed_xy
            eff.append(f'| {k0:+g} | {kp:+.2g} | {eq17_error(LINE, d, directed=True)["e_mean_cm"]:.3f} |')
            print(eff[-1], flush=True)
    out = Path(__file__).parent / 'results' / 'natural_curvature_frame.md'
    out.write_text('# The laid rod\'s material frame (benchmarks/natural_curvature_frame.py)\n\n'
                   '0.3 m rod, L_gb 3.4 cm, mu 0.5, nn plans; simulator 1 cm edges, dt 0.1 s, 0.03 m/s. d1_z: '
                   'vertical component of the material director d1 of the laid edges at the end (+1: up, the '
                   'frame NATURAL_CURVATURE_SIGN assumes); roll: arccos of its mean; d1 . left: its component towards '
                   'z x tangent.\n\n' + '\n'.join(rows) + '\n\n## Planning with an effective curvature\n\n'
                   'The 15 cm line planned as an arc of the given curvature, laid by a rod with the natural '
                   'curvature k0 (0: the line itself).\n\n' + '\n'.join(eff) + '\n')
    print(out)


if __name__ == '__main__':
    sys.exit(main())
