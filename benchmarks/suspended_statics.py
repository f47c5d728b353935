"""The suspended rod's statics in both simulators against the heavy-elastica boundary value problem (issue #10: which
simulator is right on a curve).

    PYTHONPATH=ros_ws/src/rod_deploy .venv-bench/bin/python benchmarks/suspended_statics.py [--rod 3]
        [--pattern circle] [--s 0.16,0.3,0.45,0.6] [--out NAME.md] [--commit-results]

At each laid length s: the laid part [0, s] held exactly on the planned curve (z = h), the gripper at the planned
pose for that node (the last node and the last element's directors in PyElastica; the last edge and its twist in our
DER), the rest of the rod free on a frictionless table; the rod settled to rest (PyElastica: its dynamics with
damping 5/s for ``--settle`` s from the continuum shape; our DER: its static solve, ``deployment_decomposition.
statics_check``). Compared with the continuum optimal grasp the planner assumed (``planning.optimal_grasp``, the
same BVP both simulators should reproduce): the force the laid part exerts on the suspended part at q_C (local frame:
x along the tangent, y to the left, z up), where the rod leaves the table (rod lying beyond q_C), the heading of the
first suspended element, the curvature at q_C, and the largest distance between the simulated suspended rod and the
continuum one at equal material coordinate (and its lateral, y, part).

If a simulator's suspended rod matches the BVP here, its touch-down point for a given gripper pose is the planner's,
and in the no-slip limit (friction high enough that a laid node never moves) it lays the rod on the planned curve.
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def _transport(d1, t_from, t_to):
    """Parallel transport of the unit vector d1 (normal to t_from) to the tangent t_to."""
    b = np.cross(t_from, t_to)
    nb = np.linalg.norm(b)
    if nb < 1e-14:
        return d1.copy()
    b /= nb
    ang = math.atan2(nb, float(np.dot(t_from, t_to)))
    c, s_ = math.cos(ang), math.sin(ang)
    return d1 * c + np.cross(b, d1) * s_ + b * np.dot(b, d1) * (1 - c)


def elastica_statics(pattern_name, plan, rod, s_check_m, element_m=0.005, dt_s=1.5e-4, settle_s=6.0,
                     damping_per_s=5.0, rotary_scale=100.0):
    """Rows (dicts) of the PyElastica statics at each laid length in ``s_check_m`` (see the module docstring)."""
    import elastica as ea
    from pyelastica_replay import FLIP, G, NodalCoulombStickPlane, _Simulator, rod_material, rotary_inertia_scaled
    from rod_deploy.planning.optimal_grasp import optimal_grasp
    from rod_deploy.planning.trajectory import local_frames
    pat, Lgb, h, L = plan.pattern, rod.gravito_bending_length_m, rod.radius_m, rod.length_m
    E, rho = rod_material(rod)
    A = math.pi * h ** 2
    EI = E * math.pi * h ** 4 / 4
    Rt_all = local_frames(pat.tangent)
    rows = []
    for s_c in s_check_m:
        j = int(np.argmin(np.abs(pat.s - s_c)))
        if j < 2 or j >= len(pat.s) - 1:
            continue
        cpu = time.process_time()
        Rt = Rt_all[j]
        qc = np.array([*pat.xy[j], h])
        ds_laid = float(pat.s[1] - pat.s[0])
        n_susp = max(int(round((L - pat.s[j]) / element_m)), 2)
        dl = (L - pat.s[j]) / n_susp
        n_el = j + n_susp
        ls_bar, ks_bar, kappa_bar = plan.inputs[j]
        sol = optimal_grasp(ls_bar, kappa_bar, ks_bar, method='bvp', check_stability=False).solution
        p_grip = plan.position[plan.first_grasp_index + j]
        R_grip = plan.rotation[plan.first_grasp_index + j].as_matrix()
        Q_grip = FLIP @ R_grip.T
        # rest configuration: straight, the laid part's element length ds_laid, the suspended part's dl
        lengths = np.concatenate([np.full(j, ds_laid), np.full(n_susp, dl)])
        rest = np.zeros((3, n_el + 1))
        rest[0, 1:] = np.cumsum(lengths)
        rod_e = ea.CosseratRod.straight_rod(n_el, np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]),
                                            float(lengths.sum()), h, rho, youngs_modulus=E, shear_modulus=E / 3.0,
                                            position=rest)
        rotary_inertia_scaled(rod_e, rotary_scale)
        # initial guess: laid nodes on the planned curve, suspended ones on the continuum shape (by material s)
        nodes = np.zeros((n_el + 1, 3))
        nodes[:j + 1] = np.column_stack([pat.xy[:j + 1], np.full(j + 1, h)])
        s_susp = (np.arange(j, n_el + 1) - j) * dl / Lgb
        r_bvp = np.column_stack([np.interp(np.minimum(s_susp, sol.s[-1]), sol.s, sol.r[:, k]) for k in range(3)])
        nodes[j:] = qc + (Rt @ r_bvp.T).T * Lgb
        nodes[-1] = p_grip
        nodes[-2] = p_grip - dl * Q_grip[2]
        t = np.diff(nodes, axis=0)
        t /= np.linalg.norm(t, axis=1)[:, None]
        Q = np.zeros((3, 3, n_el))
        d1 = Q_grip[0] - t[-1] * np.dot(Q_grip[0], t[-1])
        d1 /= np.linalg.norm(d1)
        for e in range(n_el - 1, -1, -1):         # d1 parallel-transported from the gripper's (no twist)
            if e < n_el - 1:
                d1 = _transport(d1, t[e + 1], t[e])
                d1 -= t[e] * np.dot(d1, t[e])
                d1 /= np.linalg.norm(d1)
            Q[0, :, e], Q[1, :, e], Q[2, :, e] = d1, np.cross(t[e], d1), t[e]
        Q[:, :, -1] = Q_grip
        rod_e.position_collection[:] = nodes.T
        rod_e.director_collection[:] = Q
        laid = nodes[:j + 1].T.copy()

        class Held(ea.ConstraintBase):
            def constrain_values(self, system, time):
                system.position_collection[:, :j + 1] = laid
                system.position_collection[:, -1] = p_grip
                system.director_collection[:, :, -1] = Q_grip

            def constrain_rates(self, system, time):
                system.velocity_collection[:, :j + 1] = 0.0
                system.velocity_collection[:, -1] = 0.0
                system.omega_collection[:, -1] = 0.0

        sim = _Simulator()
        plane = ea.Plane(plane_origin=np.zeros(3), plane_normal=np.array([0.0, 0.0, 1.0]))
        sim.append(plane)
        sim.append(rod_e)
        sim.constrain(rod_e).using(Held)
        sim.add_forcing_to(rod_e).using(ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -G]))
        sim.detect_contact_between(rod_e, plane).using(NodalCoulombStickPlane, k=200.0, nu=0.1, mu=0.0, dt=dt_s,
                                                        applied_normal=True)
        sim.dampen(rod_e).using(ea.AnalyticalLinearDamper, uniform_damping_constant=damping_per_s, time_step=dt_s)
        sim.finalize()
        stepper = ea.PositionVerlet()
        now = np.float64(0.0)
        steps = int(round(settle_s / dt_s))
        avg_from = steps - int(round(0.5 / dt_s))          # the last 0.5 s averaged (the contact chatters by ~1 um)
        F, x, x2, n_avg = np.zeros(3), np.zeros((n_el + 1, 3)), np.zeros((n_el + 1, 3)), 0
        for k in range(steps):
            now = stepper.step(sim, now, dt_s)
            if k >= avg_from and k % 10 == 0:
                # the force the laid part exerts on the suspended part at q_C: minus the elastic forces on the laid
                # nodes
                F -= rod_e.internal_forces[:, :j + 1].sum(axis=1)
                x += rod_e.position_collection.T
                x2 += rod_e.position_collection.T ** 2
                n_avg += 1
        F, x = F / n_avg, x / n_avg
        # how far from rest: the largest standard deviation of a node's position over the averaged 0.5 s
        speed = float(np.max(np.sqrt(np.maximum(x2 / n_avg - x ** 2, 0.0))))
        F_loc = Rt.T @ F
        F_plan = sol.clamp_force * EI / Lgb ** 2
        lifted = np.flatnonzero(x[j + 1:, 2] > h + 1e-5)
        extra = (int(lifted[0]) if lifted.size else n_susp) * dl
        t_out = x[j + 1] - x[j]
        heading = np.degrees(np.arctan2(t_out @ Rt[:, 1], t_out @ Rt[:, 0]))
        e0, e1 = x[j] - x[j - 1], x[j + 1] - x[j]
        kappa_c = 2 * (e0[0] * e1[1] - e0[1] * e1[0]) / (np.linalg.norm(e0[:2]) * np.linalg.norm(e1[:2]) +
                                                  float(np.dot(e0[:2], e1[:2]))) / (0.5 * (ds_laid + dl))
        r_sim = (Rt.T @ (x[j:] - qc).T).T / Lgb
        d = (r_sim - r_bvp) * Lgb
        rows.append(dict(pattern=pattern_name, sim='PyElastica', s_m=float(pat.s[j]), kappa_bar=float(kappa_bar),
                         Fx=F_loc[0], Fy=F_loc[1], Fz=F_loc[2], Fx_plan=F_plan[0], Fy_plan=F_plan[1],
                         Fz_plan=F_plan[2], extra_on_table_mm=1000 * extra, heading_deg=float(heading),
                         kappa_c=float(kappa_c), kappa_pattern=float(pat.kappa[j]),
                         shape_mm=1000 * float(np.max(np.linalg.norm(d, axis=1))),
                         lateral_mm=1000 * float(d[np.argmax(np.abs(d[:, 1])), 1]),
                         residual=speed, cpu_s=time.process_time() - cpu))
    return rows


def der_statics(pattern_name, P, rod, s_check_m):
    """The same check in our DER (``deployment_decomposition.statics_check``), rows in this module's columns."""
    from deployment_decomposition import statics_check
    from rod_deploy.planning.trajectory import PlannerSettings
    out = []
    for r in statics_check(pattern_name, P, rod, PlannerSettings(), s_check_m):
        out.append(dict(pattern=r['pattern'], sim='our DER', s_m=r['s_m'], kappa_bar=r['kappa_bar'],
                        Fx=r['Fx'], Fy=r['Fy'], Fz=r['Fz'], Fx_plan=r['Fx_plan'], Fy_plan=r['Fy_plan'],
                        Fz_plan=r['Fz_plan'], extra_on_table_mm=r['extra_on_table_mm'],
                        heading_deg=r['heading_deg'], kappa_c=r['kappa_c'], kappa_pattern=r['kappa_pattern'],
                        shape_mm=r['shape_mm'], lateral_mm=float('nan'), residual=r['residual'], cpu_s=float('nan')))
    return out


def main():
    from deployment_table import RODS, all_patterns
    from results_dir import add_results_argument, results_path
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rod', type=int, default=3)
    ap.add_argument('--pattern', default='circle')
    ap.add_argument('--s', default='0.16,0.3,0.45,0.6', help='laid lengths [m]')
    ap.add_argument('--settle', type=float, default=6.0, help='PyElastica settling time [s]')
    ap.add_argument('--element', type=float, default=0.005, help='PyElastica element length [m]')
    ap.add_argument('--dt', type=float, default=1.5e-4)
    ap.add_argument('--no-der', action='store_true')
    ap.add_argument('--out', default='suspended_statics.md')
    add_results_argument(ap)
    args = ap.parse_args()
    rod = rod_description_from_dict(RODS[args.rod])
    P = all_patterns(args.pattern)[args.pattern]
    s_check = [float(v) for v in args.s.split(',')]
    plan = plan_trajectory(P, rod, PlannerSettings())
    t0 = time.perf_counter()
    rows = elastica_statics(args.pattern, plan, rod, s_check, element_m=args.element, dt_s=args.dt,
                            settle_s=args.settle)
    if not args.no_der:
        rows += der_statics(args.pattern, P, rod, s_check)
    rows.sort(key=lambda r: (r['s_m'], r['sim']))
    head = ('| s m | kappa_bar | simulator | Fx mN | Fy mN | Fy BVP | Fz mN | Fz BVP | rod on table beyond q_C mm | '
            'heading deg | kappa at q_C 1/m | kappa pattern | shape vs BVP mm | lateral part mm | '
            'not at rest: PyEl. largest node std over 0.5 s, um; DER Newton residual | CPU s |')
    lines = [f'# Suspended rod statics against the BVP, both simulators: `benchmarks/suspended_statics.py --rod '
             f'{args.rod} --pattern {args.pattern} --s {args.s} --settle {args.settle} --element {args.element} '
             f'--dt {args.dt}`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; '
             f'{time.perf_counter() - t0:.0f} s wall. Rod #{args.rod}, the default nn plan; laid part held on the '
             'planned curve, gripper at the planned pose, frictionless table beyond q_C. Forces: the laid part on '
             'the suspended part at q_C, local frame (x tangent, y left, z up), mN; BVP = the continuum optimal '
             'grasp (Fx BVP = 0). PyElastica: the last 0.5 s averaged. See the script docstring.', '', head,
             '|' + '---|' * (head.count('|') - 1)]
    for r in rows:
        lines.append(f"| {r['s_m']:.3f} | {r['kappa_bar']:+.3f} | {r['sim']} | {1e3 * r['Fx']:+.3f} | "
                     f"{1e3 * r['Fy']:+.3f} | {1e3 * r['Fy_plan']:+.3f} | {1e3 * r['Fz']:+.3f} | "
                     f"{1e3 * r['Fz_plan']:+.3f} | {r['extra_on_table_mm']:.1f} | {r['heading_deg']:+.2f} | "
                     f"{r['kappa_c']:+.2f} | {r['kappa_pattern']:+.2f} | {r['shape_mm']:.2f} | "
                     f"{r['lateral_mm']:+.2f} | {(1e6 * r['residual'] if r['sim'] == 'PyElastica' else r['residual']):.1e} | "
                     f"{r['cpu_s']:.0f} |")
    text = '\n'.join(lines) + '\n'
    print(text)
    out = results_path(args, args.out)
    if out:
        Path(out).write_text(text)
        print(f'wrote {out}')


if __name__ == '__main__':
    main()
