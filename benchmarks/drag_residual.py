"""What the drag compensation at bends misses (issue #10): the template the simulation-in-the-loop refinement
converges to against the drag compensation's template, node by node along the pattern.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/drag_residual.py \
        [--cases 3:medium:letterA,3:medium:letterC] [--refine 4] [--save-dir out/drag_residual] [--commit-results]

Per case (rod, friction, pattern): the default plan (drag compensation on) simulated in our DER (its deployment D_0),
then ``refinement.refine`` with ``--refine`` template simulations (the planner, drag compensation on, plans each
template T: what it plans for is T moved by the drag offsets of T). Per node of the drawn pattern P (arc length s
from the free end), along P's left normal, all in mm: the default template's offset (``drag_offsets``), the offset
of what the refined plan was planned for (T_best and its own drag offsets), their difference (what the
one-constant model misses), D_0's sideways deviation from P and its lag along the curve (D_0's arc length at P's
nearest point minus s). Beside them the planner's kappa_bar (the uncompensated plan's, as the drag model sees it),
the friction demand D and capacity mu F_z. Each case's arrays go to ``--save-dir`` as .npz for the fit
(``benchmarks/drag_model_fit.py``); the summary per 4 cm stretch to ``drag_residual.md``.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402


def signed_normal_distance(xy, normal, curve):
    """Per point of ``xy`` the signed distance along ``normal`` to the nearest point of the polyline ``curve``,
    and that nearest point's arc length along ``curve``."""
    from rod_deploy.deployment.metrics import arc_length
    c = np.asarray(curve, float)[:, :2]
    a, b = c[:-1], c[1:]
    ab = b - a
    ab2 = np.maximum(np.sum(ab * ab, axis=1), 1e-24)
    u = np.clip(np.einsum('pkj,kj->pk', xy[:, None, :] - a[None], ab) / ab2, 0.0, 1.0)
    closest = a[None] + u[..., None] * ab[None]
    k = np.argmin(np.sum((closest - xy[:, None, :]) ** 2, axis=2), axis=1)
    nearest = closest[np.arange(len(xy)), k]
    sc = arc_length(c)
    s_near = sc[k] + u[np.arange(len(xy)), k] * np.sqrt(ab2[k])
    return np.sum((nearest - xy) * normal, axis=1), s_near


def run_case(rod_id, fr, name, n_refine, save_dir):
    from deployment_table import RODS, all_patterns
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.deployment.refinement import (Candidate, Deployment, ForwardModel, RefinementSettings, refine)
    from rod_deploy.deployment.simulate import FRICTION_LEVELS, SimulationSettings
    from rod_deploy.planning.bend_drag import friction_demand
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

    rod = rod_description_from_dict(RODS[rod_id])
    mu = FRICTION_LEVELS[fr]
    P = all_patterns(name)[name]
    planner = PlannerSettings(friction=mu)
    c0 = time.process_time()
    plan0 = plan_trajectory(P, rod, planner)
    raw = plan_trajectory(P, rod, PlannerSettings(friction=mu, drag_compensation=False))
    g = plan0.drawn_pattern
    normal = np.column_stack([-g.tangent[:, 1], g.tangent[:, 0]])
    kb = np.interp(g.s, raw.pattern.s, raw.inputs[:, 2])
    D, fz = friction_demand(g.s / rod.gravito_bending_length_m, kb)
    start_m = raw.start_replacement()[0]
    t_default = plan0.template.xy if plan0.template is not None else g.xy
    off_default, _ = signed_normal_distance(g.xy, normal, t_default)
    sim = SimulationSettings(friction=mu)
    dep = Deployment(plan0.t, plan0.position, plan0.quaternion, tuple(P[0][:2]))
    model = ForwardModel(dep, sim)
    d0 = model.deployed(rod, 'default plan')
    e0 = eq17_error(P, d0)['e_mean_cm']
    dev0, s0 = signed_normal_distance(g.xy, normal, d0)
    start = Candidate(eq17_error(P, d0, directed=True)['e_mean_cm'], dep, d0, False, rod.gravito_bending_length_m,
                      plan0, model.result)
    best, n, record = refine(P, rod, rod, start, planner, sim, RefinementSettings(simulations=n_refine))
    bp = best.plan if best.replanned else plan0
    t_ref = bp.template.xy if bp.template is not None else bp.drawn_pattern.xy
    off_ref, _ = signed_normal_distance(g.xy, normal, t_ref)
    dev1, s1 = signed_normal_distance(g.xy, normal, best.deployed_xy)
    e1 = eq17_error(P, best.deployed_xy)['e_mean_cm']
    cpu = time.process_time() - c0
    out = dict(s=g.s, xy=g.xy, normal=normal, kappa_bar=kb, D=D, fz=fz, mu=mu, Lgb=rod.gravito_bending_length_m,
               start_m=start_m, off_default=off_default, off_refined=off_ref, dev0=dev0, lag0=s0 - g.s, dev1=dev1,
               lag1=s1 - g.s, e0=e0, e1=e1, rod=rod_id, friction=fr, name=name, d0=d0, d1=best.deployed_xy,
               t_refined=t_ref, t_default=t_default)
    if save_dir:
        Path(save_dir).mkdir(parents=True, exist_ok=True)
        np.savez(Path(save_dir) / f'{name}_rod{rod_id}_{fr}.npz', **out)
    gains = ','.join(f'{h["gain"]:g}{"+" if h.get("accepted") else "-"}' for h in record['iterations'])
    return out, f'{n + 1} simulations, gains {gains}, CPU {cpu:.0f} s'


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--cases', default='3:medium:letterA,3:medium:letterC')
    ap.add_argument('--refine', type=int, default=4)
    ap.add_argument('--save-dir', default='out/drag_residual')
    ap.add_argument('--out-name', default='drag_residual.md')
    add_results_argument(ap)
    args = ap.parse_args()
    t_all = time.perf_counter()
    lines = ['# What the drag compensation misses: refined templates against the drag compensation\'s, '
             '`python benchmarks/drag_residual.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{os.getloadavg()[0]:.1f} at the start). Offsets along the pattern\'s left normal, mm; s from the free '
             f'end. default: the drag compensation\'s template; refined: what the refined plan was planned for '
             f'(the refinement\'s template and its drag offsets; {args.refine} template simulations); missed = '
             'refined - default; dev D_0: the default deployment\'s sideways deviation, lag D_0 its lag along the '
             'curve (negative: behind). Per 4 cm stretch the values at the node of the largest |missed|.', '']
    for case in args.cases.split(','):
        rod_id, fr, name = case.split(':')
        t0 = time.perf_counter()
        o, note = run_case(int(rod_id), fr, name, args.refine, args.save_dir)
        print(f'{case}: e_mean {o["e0"]:.3f} -> {o["e1"]:.3f} cm ({note}, {time.perf_counter() - t0:.0f} s)',
              flush=True)
        lines += [f'## rod #{rod_id}, {fr}, {name}: e_mean {o["e0"]:.3f} (default) -> {o["e1"]:.3f} cm (refined; '
                  f'{note}); friction-limited start {100 * o["start_m"]:.1f} cm', '',
                  '| s cm | kappa_bar | D | mu F_z | default mm | refined mm | missed mm | dev D_0 mm | lag D_0 mm |',
                  '|---|---|---|---|---|---|---|---|---|']
        s = o['s']
        miss = o['off_refined'] - o['off_default']
        for a in np.arange(0.0, s[-1], 0.04):
            k = np.flatnonzero((s >= a) & (s < a + 0.04))
            if k.size == 0:
                continue
            i = k[np.argmax(np.abs(miss[k]))]
            lines.append(f'| {100 * a:.0f}-{100 * (a + 0.04):.0f} | {o["kappa_bar"][i]:.2f} | {o["D"][i]:.2f} | '
                         f'{o["mu"] * o["fz"][i]:.2f} | {1e3 * o["off_default"][i]:.1f} | '
                         f'{1e3 * o["off_refined"][i]:.1f} | {1e3 * miss[i]:.1f} | {1e3 * o["dev0"][i]:.1f} | '
                         f'{1e3 * o["lag0"][i]:.1f} |')
        lines.append('')
        out = results_path(args, args.out_name)
        out.write_text('\n'.join(lines + [f'{time.perf_counter() - t_all:.0f} s in all.']) + '\n')
    print(f'results: {results_path(args, args.out_name)}')


if __name__ == '__main__':
    main()
