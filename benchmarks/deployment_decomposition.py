"""Where the simulated deployment error comes from: controlled runs, one change at a time from the baseline.

    python benchmarks/deployment_decomposition.py [--rod 3] [--patterns circle,sine,letterC,letterA]
                                                  [--variants all] [--tag NAME] [--commit-results]

Baseline: our network's plan (``nn``) as it was before this study (equal spline weights, tangent start), the
paper's rod (default #3), medium friction (0.5), our DER simulator with
its defaults (5 mm edges, dt 0.02 s, gripper at 0.01 m/s, the free end released after the lead-in). Variants, each
changing one thing: ``hold`` the free end pinned throughout (``hold_free_end='always'``); ``slow`` the gripper at
half speed (0.005 m/s); ``fine`` 2.5 mm edges; ``numeric`` the numeric planner instead of the network; ``mu1`` high
friction (1.0); planner changes: ``ends`` the spline's end weights (``PlannerSettings.end_weight``), ``start`` the
friction-limited start (``PlannerSettings.start='achievable'``), ``both``, ``both_half`` (both, counting on half
the friction: ``friction_share=0.5``).

Besides Eq. 17 each run reports the part of the error a rigid motion of the deployed curve removes (``e_rigid``:
e_mean after the best rotation + translation, Kabsch on the N = 50 resampled points), how far the free end moved
from the pattern's first point, and the angle between the first 3 cm of the deployed curve and of the pattern.
The deployed shapes are saved (npz) next to the table for plots.

Second round (why curved starts turn): options applied to every run, ``--clamp-nodes K`` (the first K nodes held on
the planned start all along: a start that carries a moment, ``SimulationSettings.clamp_start_xy``),
``--friction-velocity``, ``--dt``, ``--gripper-speed`` (``--exact-length``, the rod at its own rest length, is gone:
that is the simulator's only set-up since h-simcheck; the results files with it predate that); variants ``achievable`` (the planner's current friction-limited start) and ``remainder`` (the
paper's remainder, ``with_remainder``: rod laid before P(0), cut off the deployed curve before scoring); and
``--statics S1,S2,..`` (no time stepping: the DER statics at those contact points against the continuum grasp the
planner assumed, ``statics_check``; writes ``deployment_statics*.md``).

``--truncate-m X`` (exploration on a loaded machine): only the first X m of each pattern, laid by a rod X + 0.2 m
long (the same L_gb and radius), about 4x cheaper than the full 0.9 m deployment.
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from dataclasses import replace

import numpy as np

from deployment_table import RODS, all_patterns
from results_dir import add_results_argument, results_path
from rod_deploy.deployment.metrics import eq17_error, resample
from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

#: the planner as it was (equal spline weights, tangent start): the 'after' table in benchmarks/results/HISTORY.md
BASE_PLAN = PlannerSettings(end_weight=1.0, start='tangent')
BASE_SIM = SimulationSettings(friction=0.5)
VARIANTS = {
    'base': (BASE_PLAN, BASE_SIM),
    'hold': (BASE_PLAN, replace(BASE_SIM, hold_free_end='always')),
    'slow': (BASE_PLAN, replace(BASE_SIM, max_gripper_speed_m_s=0.005)),
    'fine': (BASE_PLAN, replace(BASE_SIM, edge_length_m=0.0025)),
    'numeric': (replace(BASE_PLAN, method='numeric'), BASE_SIM),
    'mu1': (BASE_PLAN, replace(BASE_SIM, friction=1.0)),
    'ends': (replace(BASE_PLAN, end_weight=PlannerSettings().end_weight), BASE_SIM),
    # start, both, both_half: their shares now refer to the corrected bound mu w s^2 / 4 (round 1 ran them with the
    # earlier mu w s^2 / 2: both_half then = achievable now)
    'start': (replace(BASE_PLAN, start='achievable', friction_share=1.0), BASE_SIM),
    'both': (replace(BASE_PLAN, end_weight=PlannerSettings().end_weight, start='achievable', friction_share=1.0),
             BASE_SIM),
    'both_half': (replace(BASE_PLAN, end_weight=PlannerSettings().end_weight, start='achievable',
                          friction_share=0.5), BASE_SIM),
    # the planner's current friction-limited start (default share; since the bound's correction, share 1 of
    # mu w s^2 / 4 = the plans of both_half before it)
    'achievable': (replace(BASE_PLAN, end_weight=PlannerSettings().end_weight, start='achievable',
                           friction_share=PlannerSettings().friction_share), BASE_SIM),
    # the paper's remainder (Sec. 6.4.1): a lead of rod laid before P(0), curvature growing within the friction
    # bound (with_remainder), not scored; then the tangent start
    'remainder': (replace(BASE_PLAN, end_weight=PlannerSettings().end_weight), BASE_SIM),
}
REMAINDER_SHARE = 0.5          # share c of the friction the remainder counts on (as the achievable start's default)


def with_remainder(P, rod, friction=0.5, share=REMAINDER_SHARE, start_zone_m=0.1, ds=0.001):
    """The pattern with a remainder prepended: on sigma in [0, l] from the new free end the curvature
    sign(kappa_0) min(|kappa_0|, kappa_max(sigma)) (the achievable start's bound), ending at P(0) with the pattern's
    heading and curvature; l the least length after which the pattern's first ``start_zone_m`` stays within the bound.
    Returns (points, l)."""
    from rod_deploy.planning.achievable_start import friction_curvature_limit, start_length_needed_m
    from rod_deploy.planning.trajectory import process_pattern
    Lgb = rod.gravito_bending_length_m
    pat = process_pattern(P)
    zone = pat.s <= start_zone_m
    need = start_length_needed_m(np.abs(pat.kappa[zone]) * Lgb, Lgb, friction, share) - pat.s[zone]
    ell = float(np.ceil(max(need.max(), 0.0) / ds) * ds)
    if ell == 0.0:
        return P, 0.0
    sigma = np.arange(0.0, ell + ds / 2, ds)
    k0 = pat.kappa[0]
    kappa = np.sign(k0) * np.minimum(abs(k0), friction_curvature_limit(sigma, Lgb, friction, share))
    th0 = np.arctan2(pat.tangent[0, 1], pat.tangent[0, 0])
    # heading at sigma: th0 minus the turning still to come on [sigma, l] (trapezoids), integrated back from P(0)
    turn = np.concatenate([[0.0], np.cumsum(0.5 * (kappa[1:] + kappa[:-1]) * ds)])
    th = th0 - (turn[-1] - turn)
    step = 0.5 * (np.column_stack([np.cos(th), np.sin(th)])[1:] + np.column_stack([np.cos(th), np.sin(th)])[:-1]) * ds
    pos = pat.xy[0] - np.concatenate([np.cumsum(step[::-1], axis=0)[::-1], [[0.0, 0.0]]])
    return np.vstack([pos[:-1], P]), ell


def cut_start(xy, length_m):
    """The curve ``xy`` without its first ``length_m`` of arc length (the remainder)."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    k = int(np.searchsorted(s, length_m))
    if k == 0:
        return xy
    a = (length_m - s[k - 1]) / max(s[k] - s[k - 1], 1e-15)
    return np.vstack([xy[k - 1] + a * (xy[k] - xy[k - 1]), xy[k:]])


def rigid_residual_cm(pattern_xy, deployed_xy, n=50):
    """e_mean after the best rigid motion (rotation + translation) of the deployed curve onto the pattern [cm]."""
    lp = float(np.sum(np.linalg.norm(np.diff(pattern_xy, axis=0), axis=1)))
    a = resample(pattern_xy, n)
    b = resample(deployed_xy, n, length=lp)
    ca, cb = a.mean(0), b.mean(0)
    U, _, Vt = np.linalg.svd((b - cb).T @ (a - ca))
    D = np.diag([1.0, np.sign(np.linalg.det(U @ Vt))])
    R = (U @ D @ Vt).T
    b_fit = (b - cb) @ R.T + ca
    return 100 * float(np.mean(np.linalg.norm(a - b_fit, axis=1)))


def start_angle_deg(pattern_xy, deployed_xy, length_m=0.03):
    def heading(xy):
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
        k = int(np.searchsorted(s, length_m))
        d = xy[min(k, len(xy) - 1)] - xy[0]
        return np.arctan2(d[1], d[0])
    a = heading(deployed_xy) - heading(pattern_xy)
    return float(np.degrees((a + np.pi) % (2 * np.pi) - np.pi))


def friction_needed(force_y_N, moment_z_Nm, laid_m, weight_N_m, n_dir=3600, n_quad=400):
    """Smallest Coulomb coefficient with which friction on a straight laid stretch [0, s] (uniform weight w per
    length, rigid) holds a sideways force F_y and a moment M_z applied at its end s: the gauge of (F_y, M_z) in the
    set {(int f, int f (x - s)) : |f| <= w}, max over directions (a, b) of (a F + b M) / int w |a + b (x - s)| dx."""
    y = (np.arange(n_quad) + 0.5) / n_quad * laid_m - laid_m            # x - s, midpoints
    phi = np.linspace(0.0, np.pi, n_dir, endpoint=False)
    a, b = np.cos(phi), np.sin(phi) / laid_m                         # b scaled: both terms of order 1
    support = weight_N_m * laid_m / n_quad * np.sum(np.abs(a[:, None] + b[:, None] * y[None]), axis=1)
    return float(np.max(np.abs(a * force_y_N + b * moment_z_Nm) / support))


def statics_check(pattern_name, P, rod, plan_s, s_check_m, friction=0.5, edge_m=0.005):
    """Planner-simulator consistency without time stepping: at each arc length in ``s_check_m`` the laid part
    [0, s] clamped exactly on the planned curve (z = h), the gripper at the planned pose (the last edge along
    -z_gripper, its twist d1 = x_gripper), the suspended part solved by the DER statics on a frictionless table
    (started from the continuum optimal-grasp shape). Compared with what the planner assumed (the continuum optimal
    grasp): the force and the moment the deployed part exerts on the suspended part at q_C, where the rod leaves
    the table, its curvature and heading there. Rows: dicts."""
    from rod_deploy.deployment.simulate import held_edge_twist, material_parameters
    from rod_deploy.physics.der_simulator import DiscreteElasticRod
    from rod_deploy.planning.optimal_grasp import optimal_grasp
    from rod_deploy.planning.trajectory import local_frames
    plan = plan_trajectory(P, rod, plan_s)
    pat, Lgb, h, L = plan.pattern, rod.gravito_bending_length_m, rod.radius_m, rod.length_m
    params = material_parameters(rod, friction, 0.0)
    EI, w = params.EI, params.rho_A * 9.81
    Rt_all = local_frames(pat.tangent)
    rows = []
    for s_c in s_check_m:
        j = int(np.argmin(np.abs(pat.s - s_c)))        # the planned node nearest to s_c
        if j < 2 or j >= len(pat.s) - 1:
            continue
        Rt = Rt_all[j]
        qc = np.array([*pat.xy[j], h])
        # the laid part: the rod's first pat.s[j] of length on the planned nodes (uniform, at most step_m apart), the
        # suspended part L - pat.s[j] in edges of about edge_m (the planner's nodes are no longer exactly edge_m apart)
        ds_laid = float(pat.s[1] - pat.s[0])
        n_susp = max(int(round((L - pat.s[j]) / edge_m)), 2)
        dl = (L - pat.s[j]) / n_susp
        n_edges = j + n_susp
        ls_bar, ks_bar, kappa_bar = plan.inputs[j]
        g = optimal_grasp(ls_bar, kappa_bar, ks_bar, method='bvp', check_stability=False)
        sol = g.solution
        # initial guess: laid nodes on the planned curve, suspended ones on the continuum shape (by arc length)
        nodes = np.zeros((n_edges + 1, 3))
        nodes[:j + 1] = np.column_stack([pat.xy[:j + 1], np.full(j + 1, h)])
        s_susp = (np.arange(j, n_edges + 1) - j) * dl / Lgb
        r_loc = np.column_stack([np.interp(np.minimum(s_susp, sol.s[-1]), sol.s, sol.r[:, k]) for k in range(3)])
        nodes[j:] = qc + (Rt @ r_loc.T).T * Lgb
        p_grip = plan.position[plan.first_grasp_index + j]
        R_grip = plan.rotation[plan.first_grasp_index + j].as_matrix()
        nodes[-1] = p_grip
        nodes[-2] = p_grip + dl * R_grip[:, 2]
        rod_model = DiscreteElasticRod(nodes, replace(params, friction=0.0), d1_first=None)
        # rest lengths: the rod's own (the laid part's node spacing, dl), not the initial guess's
        rod_model.rest_lengths[:] = np.concatenate([np.full(j, ds_laid), np.full(n_susp, dl)])
        rod_model.voronoi[:] = 0.5 * (rod_model.rest_lengths[1:] + rod_model.rest_lengths[:-1])
        for i in range(j + 1):
            rod_model.clamp_node(i)
        rod_model.clamp_node(n_edges)
        rod_model.clamp_node(n_edges - 1)
        theta = 0.0
        for _ in range(3):            # twist of the held edge: d1 = x_gripper (its reference frame moves with it)
            theta = held_edge_twist(rod_model, R_grip, theta)
            rod_model.set_positions(rod_model.theta_dof(n_edges - 1), theta)
            rod_model.clamp_theta(n_edges - 1)
            res = rod_model.static_solve(tol=1e-9, max_iter=200)
        x = rod_model.nodes
        # the deployed part's action on the suspended part at q_C: the clamp's net reaction on the laid nodes
        reac = rod_model.reaction_forces()
        f_nodes = np.array([reac[rod_model.node_dof(i)] for i in range(j + 1)])
        F = f_nodes.sum(0)
        F[2] -= w * pat.s[j]                       # the laid part's own weight (the table carries it)
        M = np.sum(np.cross(x[:j + 1] - x[j], f_nodes), axis=0)
        F_loc, M_loc = Rt.T @ F, Rt.T @ M
        F_plan = Rt.T @ Rt @ (sol.clamp_force * EI / Lgb ** 2)     # the continuum's, local frame [N]
        M_plan = sol.clamp_moment * EI / Lgb
        # where the rod leaves the table: the last node in contact after q_C
        lifted = np.flatnonzero(x[j + 1:, 2] > h + 1e-5)
        extra = int(lifted[0]) if lifted.size else n_edges - j
        t_out = x[j + 1] - x[j]
        heading = np.degrees(np.arctan2(t_out @ Rt[:, 1], t_out @ Rt[:, 0]))
        pitch = np.degrees(np.arcsin(t_out[2] / np.linalg.norm(t_out)))
        # curvature at q_C (turning between the last laid edge and the first suspended one, horizontal)
        e0, e1 = x[j] - x[j - 1], x[j + 1] - x[j]
        kappa_c = 2 * (e0[0] * e1[1] - e0[1] * e1[0]) / (np.linalg.norm(e0[:2]) * np.linalg.norm(e1[:2]) +
                                                  float(np.dot(e0[:2], e1[:2]))) / (0.5 * (ds_laid + dl))
        r_der = (Rt.T @ (x[j:] - qc).T).T / Lgb
        r_bvp = np.column_stack([np.interp(s_susp, sol.s, sol.r[:, k]) for k in range(3)])   # by material s
        shape_mm = 1000 * Lgb * float(np.max(np.linalg.norm(r_der - r_bvp, axis=1)))
        rows.append(dict(pattern=pattern_name, s_m=float(pat.s[j]), kappa_bar=float(kappa_bar),
                         Fx=F_loc[0], Fy=F_loc[1], Fz=F_loc[2], Mz=M_loc[2],
                         Fx_plan=F_plan[0], Fy_plan=F_plan[1], Fz_plan=F_plan[2], Mz_plan=M_plan[2],
                         Mz_pattern=EI * pat.kappa[j], extra_on_table_mm=1000 * extra * dl,
                         heading_deg=float(heading), pitch_deg=float(pitch), kappa_c=float(kappa_c),
                         kappa_pattern=float(pat.kappa[j]), shape_mm=shape_mm,
                         friction_force_N=friction * w * pat.s[j],
                         friction_moment_Nm=friction * w * pat.s[j] ** 2 / 2, residual=res,
                         mu_needed=friction_needed(F_loc[1], M_loc[2], pat.s[j], w)))
    return rows


def write_statics(args, patterns, rod, variants, s_check):
    t_all = time.perf_counter()
    tag = f'_{args.tag}' if args.tag else ''
    out = results_path(args, f'deployment_statics{tag}.md')
    lines = [f'# Planner-simulator consistency, statics only: `python benchmarks/deployment_decomposition.py '
             f'--rod {args.rod} --patterns {args.patterns} --variants {args.variants} --statics {args.statics}'
             f'{f" --truncate-m {args.truncate_m}" if args.truncate_m else ""}`', '',
             'The laid part clamped on the planned curve, the gripper at the planned pose, DER statics (5 mm edges, '
             'frictionless table, contact radius h) against the continuum optimal grasp the planner assumed. F, M: '
             'the deployed part\'s action on the suspended part at q_C, local frame (x along the tangent, y to the '
             'left, z up), DER / planned [mN, mN m]; Mz pattern: EI kappa of the pattern; extra: rod lying on the '
             'table beyond q_C; heading, pitch: of the first suspended edge; kappa at q_C DER vs pattern [1/m]; '
             'shape: largest distance DER - continuum suspended shape at the same material point; capacities: mu w s and mu w s^2 / 2 (mu 0.5); '
             'mu needed: the least friction coefficient with which a rigid straight laid stretch [0, s] holds the DER '
             '(Fy, Mz) (`friction_needed`).',
             '', '| pattern | variant | s m | kappa_bar | Fx | Fx plan | Fy | Fy plan | Fz | Fz plan | Mz | Mz plan | '
             'Mz pattern | extra mm | heading deg | pitch deg | kappa DER | kappa pattern | shape mm | mu w s | '
             'mu w s^2/2 | mu needed |', '|' + '---|' * 22]
    for name, P in patterns.items():
        for v in variants:
            for r in statics_check(name, P, rod, VARIANTS[v][0], s_check):
                lines.append(f"| {name} | {v} | {r['s_m']:.3f} | {r['kappa_bar']:+.3f} | {1e3 * r['Fx']:+.3f} | "
                             f"{1e3 * r['Fx_plan']:+.3f} | {1e3 * r['Fy']:+.3f} | {1e3 * r['Fy_plan']:+.3f} | "
                             f"{1e3 * r['Fz']:+.3f} | {1e3 * r['Fz_plan']:+.3f} | {1e3 * r['Mz']:+.4f} | "
                             f"{1e3 * r['Mz_plan']:+.4f} | {1e3 * r['Mz_pattern']:+.4f} | "
                             f"{r['extra_on_table_mm']:.0f} | {r['heading_deg']:+.2f} | {r['pitch_deg']:+.2f} | "
                             f"{r['kappa_c']:+.2f} | {r['kappa_pattern']:+.2f} | {r['shape_mm']:.2f} | "
                             f"{1e3 * r['friction_force_N']:.3f} | {1e3 * r['friction_moment_Nm']:.4f} | {r['mu_needed']:.2f} |")
                print(lines[-1], flush=True)
    lines.insert(3, f'{time.perf_counter() - t_all:.0f} s in all.')
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rod', type=int, default=3)
    ap.add_argument('--patterns', default='circle,sine,letterC,letterA')
    ap.add_argument('--variants', default='all', help=f'comma-separated from {",".join(VARIANTS)}, or all')
    ap.add_argument('--truncate-m', type=float, default=None, help='only the first X m of each pattern, rod X + 0.2 m')
    ap.add_argument('--tag', default='', help='suffix of the results file (parallel runs)')
    ap.add_argument('--clamp-nodes', type=int, default=0,
                    help='hold the first K nodes on the planned start all along (K >= 2: a clamped start that '
                         'carries a moment; SimulationSettings.clamp_start_xy); 0: off')
    ap.add_argument('--friction-velocity', type=float, default=None, help='friction regularisation [m/s] (all runs)')
    ap.add_argument('--statics', default=None, metavar='S1,S2,...',
                    help='instead of deployments: the statics check (statics_check) at these arc lengths [m]')
    ap.add_argument('--dt', type=float, default=None, help='time step [s] (all runs)')
    ap.add_argument('--gripper-speed', type=float, default=None, help='replay speed [m/s] (all runs)')
    add_results_argument(ap)
    args = ap.parse_args()
    rod_dict = dict(RODS[args.rod])
    patterns = all_patterns(args.patterns)
    if args.truncate_m:
        rod_dict['length'] = args.truncate_m + 0.2
        for name, P in patterns.items():
            s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
            patterns[name] = P[s <= args.truncate_m]
    rod = rod_description_from_dict(rod_dict)
    variants = list(VARIANTS) if args.variants == 'all' else args.variants.split(',')
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        ap.error(f'unknown variant(s) {", ".join(unknown)} (one of {", ".join(VARIANTS)})')
    if args.clamp_nodes == 1 or args.clamp_nodes < 0:
        ap.error('--clamp-nodes must be 0 (off) or at least 2')
    overrides = {k: v for k, v in (('friction_velocity_m_s', args.friction_velocity), ('dt_s', args.dt),
                                   ('max_gripper_speed_m_s', args.gripper_speed)) if v is not None}
    tag = f'_{args.tag}' if args.tag else ''
    out = results_path(args, f'deployment_decomposition{tag}.md')
    if args.statics:
        return write_statics(args, patterns, rod, variants, [float(v) for v in args.statics.split(',')])
    rows, shapes = [], {}
    t_all = time.perf_counter()
    for name, P in patterns.items():
        for v in variants:
            plan_s, sim_s = VARIANTS[v]
            t0 = time.perf_counter()
            P_plan, ell = with_remainder(P, rod) if v == 'remainder' else (P, 0.0)
            plan = plan_trajectory(P_plan, rod, plan_s)
            sim_s = replace(sim_s, **overrides)
            if args.clamp_nodes:
                sim_s = replace(sim_s, clamp_start_xy=plan.pattern.xy[:args.clamp_nodes])
            res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod, sim_s)
            deployed = cut_start(res.deployed_xy, ell)        # the remainder is not part of the pattern
            e = eq17_error(P, deployed, directed=True)
            row = dict(pattern=name, variant=v, e_mean=e['e_mean_cm'], sigma=e['sigma_cm'],
                       e_rigid=rigid_residual_cm(P, deployed),
                       free_end_mm=1000 * float(np.linalg.norm(deployed[0] - P[0])),
                       start_deg=start_angle_deg(P, deployed), coverage=e['coverage'],
                       wall_s=time.perf_counter() - t0, remainder_m=ell)
            rows.append(row)
            shapes[f'{name}/{v}'] = deployed
            shapes[f'{name}/{v}/plan'] = plan.pattern.xy
            print(f"{name:10s} {v:8s} e_mean {row['e_mean']:.3f} cm  rigid-aligned {row['e_rigid']:.3f} cm  "
                  f"free end {row['free_end_mm']:.1f} mm  start {row['start_deg']:+.1f} deg  "
                  f"({row['wall_s']:.0f} s)", flush=True)
    np.savez_compressed(out.with_suffix('.npz'), **shapes)
    lines = [f'# Deployment error decomposition, `python benchmarks/deployment_decomposition.py '
             f'--rod {args.rod} --patterns {args.patterns} --variants {args.variants}'
             f'{f" --truncate-m {args.truncate_m}" if args.truncate_m else ""}'
             f'{f" --clamp-nodes {args.clamp_nodes}" if args.clamp_nodes else ""}'
             + ''.join(f' --{k} {v}' for k, v in (('friction-velocity', args.friction_velocity), ('dt', args.dt),
                                                  ('gripper-speed', args.gripper_speed)) if v is not None)
             + '`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores (shared, loaded); '
             f'{time.perf_counter() - t_all:.0f} s in all. Rod #{args.rod} ({rod.length_m:g} m long); '
             'baseline: nn plan, mu 0.5, 5 mm edges, '
             'dt 0.02 s, 0.01 m/s, free end released after the lead-in. e_rigid: e_mean after the best rigid '
             'motion of the deployed curve; free end: its final distance from the pattern\'s first point; start: '
             'heading of the first 3 cm, deployed minus pattern.', '',
             '| pattern | variant | e_mean cm | sigma cm | e_rigid cm | free end mm | start deg | coverage | wall s |',
             '|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        lines.append(f"| {r['pattern']} | {r['variant']} | {r['e_mean']:.3f} | {r['sigma']:.3f} | "
                     f"{r['e_rigid']:.3f} | {r['free_end_mm']:.1f} | {r['start_deg']:+.1f} | {r['coverage']:.2f} | "
                     f"{r['wall_s']:.0f} |")
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


if __name__ == '__main__':
    main()
