"""What the error of a deployment is made of (issue #10): the planned curve's own distance from the pattern (the
friction-limited start, the curvature rate limit and cap), against what the rod does on the table (the drag at
bends), with and without the drag compensation.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/error_shares.py \
        [--patterns digit6,wave_tight,digit2,letterG] [--rod 3] [--friction medium] [--out-name NAME.md] \
        [--commit-results]

Per pattern (development patterns only: the paper's 7 and the deployment table's own shapes), Eq. 17 e_mean [cm]
(N = 50) of: the start-replaced pattern (the friction-limited start only) against the pattern ("start"); the
planned curve without drag compensation against the pattern ("planned": start + rate limit + curvature cap); the
deployment of that plan in our DER (defaults of ``rod-deploy simulate``) against the pattern ("deployed off") and
against its planned curve ("off vs planned": what the rod does beyond the plan); the same for the planner's default
(drag compensation on: "deployed on", "on vs planned" against the uncompensated planned curve). The Eq. 17
distances of "deployed on" in four quarters of the pattern's length show where along the pattern the error is.
The laid nodes' inward motion after touch-down (``bend_drag_mechanism.measured_drag``) of the uncompensated run:
mean of its absolute value and the largest, mm.
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


def distances(pattern_xy, deployed_xy, n=50):
    """Eq. 17's point distances [cm] (the orientation Eq. 17 picks), n points along the pattern."""
    from rod_deploy.deployment.metrics import eq17_error, resample
    e = eq17_error(pattern_xy, deployed_xy, n)
    d = np.asarray(deployed_xy, float)[::-1] if e['reversed'] else np.asarray(deployed_xy, float)
    a = resample(pattern_xy, n)
    b = resample(d, n, length=e['pattern_length_m'])
    return 100 * np.linalg.norm(a - b, axis=1)


def main():
    from bend_drag_mechanism import measured_drag
    from deployment_table import RODS, all_patterns
    from replay_probe import run_der
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.deployment.simulate import FRICTION_LEVELS
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--patterns', default='digit6,wave_tight,digit2,letterG')
    ap.add_argument('--rod', type=int, default=3)
    ap.add_argument('--friction', default='medium')
    ap.add_argument('--out-name', default='error_shares.md')
    add_results_argument(ap)
    args = ap.parse_args()
    rod = rod_description_from_dict(RODS[args.rod])
    mu = FRICTION_LEVELS[args.friction]
    out = results_path(args, args.out_name)
    rows, t_all = [], time.perf_counter()
    for name in args.patterns.split(','):
        P = all_patterns(name)[name]
        r = {'name': name}
        for drag in (False, True):
            c0 = time.process_time()
            plan = plan_trajectory(P, rod, PlannerSettings(friction=mu, drag_compensation=drag))
            g = plan.drawn_pattern
            times, nodes, deployed, *_ = run_der((plan.t, plan.position, plan.quaternion, None), rod, mu, {}, 0.5)
            if not drag:
                start_xy = (plan.start_pattern if plan.start_pattern is not None else plan.pattern).xy
                r['start'] = eq17_error(g.xy, start_xy)['e_mean_cm']
                r['planned'] = eq17_error(g.xy, plan.pattern.xy)['e_mean_cm']
                planned_off = plan.pattern.xy
                r['off'] = eq17_error(P, deployed)['e_mean_cm']
                r['off_vs_planned'] = eq17_error(planned_off, deployed)['e_mean_cm']
                n = min(nodes.shape[1], len(g.s))
                left = np.column_stack([-g.tangent[:, 1], g.tangent[:, 0]])
                kb = np.interp(g.s, plan.pattern.s, plan.inputs[:, 2])
                # inward: towards the side the bend turns to (kappa_bar > 0 released: a right turn, inward -left)
                inward = -np.sign(kb)[:n, None] * left[:n]
                m = measured_drag(nodes, n, rod.radius_m, inward)
                r['drag_mean'] = 1e3 * float(np.nanmean(np.abs(m)))
                r['drag_max'] = 1e3 * float(np.nanmax(np.abs(m)))
            else:
                r['on'] = eq17_error(P, deployed)['e_mean_cm']
                r['on_vs_planned'] = eq17_error(planned_off, deployed)['e_mean_cm']
                d = distances(P, deployed)
                r['quarters'] = [float(q.mean()) for q in np.array_split(d, 4)]
                r['offset_mm'] = 1e3 * plan.drag_offset_max()
            r['cpu_s'] = r.get('cpu_s', 0.0) + time.process_time() - c0
        rows.append(r)
        print(r, flush=True)
        write(out, rows, t_all, args, mu)
    print(f'results: {out}')


def write(out, rows, t_all, args, mu):
    lines = [f'# What the error is made of, `python benchmarks/error_shares.py` (rod #{args.rod}, friction {mu:g})', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{os.getloadavg()[0]:.1f} at writing); {time.perf_counter() - t_all:.0f} s in all. Our DER (defaults '
             'of `rod-deploy simulate`), planner nn (closest planned curve, friction-limited start). Eq. 17 e_mean in '
             'cm; "planned": the uncompensated planned curve against the pattern (start + rate limit + cap); "vs '
             'planned": the deployed rod against that curve; quarters: the mean Eq. 17 distance of the compensated '
             'deployment in each quarter of the pattern from the free end; drag: inward motion after touch-down of '
             'the uncompensated run [mm]; offset: the template\'s largest distance from the pattern [mm].', '',
             '| pattern | start | planned | deployed off | off vs planned | deployed on | on vs planned | '
             'quarters (on) | drag mean / max mm | offset mm | CPU s |', '|---|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        lines.append(f"| {r['name']} | {r['start']:.3f} | {r['planned']:.3f} | {r['off']:.3f} | "
                     f"{r['off_vs_planned']:.3f} | {r['on']:.3f} | {r['on_vs_planned']:.3f} | "
                     f"{' / '.join(f'{q:.2f}' for q in r['quarters'])} | {r['drag_mean']:.2f} / {r['drag_max']:.2f} "
                     f"| {r['offset_mm']:.1f} | {r['cpu_s']:.0f} |")
    out.write_text('\n'.join(lines) + '\n')


if __name__ == '__main__':
    main()
