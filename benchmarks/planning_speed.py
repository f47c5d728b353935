"""Speed of planning a deployment trajectory: a 200-node pattern with the network, in-process and as the whole
`rod-deploy plan` process (start-up included), and every shape of the deployment table (the published patterns,
read in place when ../shared is present, and our own) as drawn, on rod #3 at friction 0.5; medians.

    python benchmarks/planning_speed.py [--repeats 20] [--commit-results]
    python benchmarks/planning_speed.py --profile [--commit-results]     # where the default plan's CPU time goes
"""
from __future__ import annotations

import argparse
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from results_dir import add_results_argument, results_path
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory


def spiral(n=200, step=0.005):
    th = np.linspace(0, 3 * np.pi, 4000)
    r = 0.15 - 0.03 * th / np.pi
    xy = np.column_stack([r * np.cos(th), r * np.sin(th)])
    s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    u = np.arange(n) * step
    return np.column_stack([np.interp(u, s, xy[:, 0]), np.interp(u, s, xy[:, 1])])


#: the parts of plan_trajectory the profile reports (file name, function name, what)
PARTS = [('trajectory.py', 'process_pattern', 'smoothing spline and nodes (process_pattern)'),
         ('achievable_start.py', 'achievable_start', 'friction-limited start (achievable_start, scipy trf)'),
         ('curvature_rate.py', 'closest_rate_limited_curve', 'closest planned curve (closest_rate_limited_curve)'),
         ('curvature_rate.py', 'levenberg_marquardt', '- its solver (levenberg_marquardt)'),
         ('curvature_rate.py', 'normal_equations', '-- J^T J and J^T r (normal_equations)'),
         ('curvature_rate.py', 'residuals', '-- residuals'),
         ('_linalg.py', 'cholesky', '-- Cholesky (numpy)'),
         ('_decomp_cholesky.py', 'cho_factor', '-- Cholesky (scipy cho_factor)'),
         ('trajectory.py', 'grasps', 'grasps from the network (grasps)'),
         ('neural_controller.py', 'load_grasp_network', '- reading the weights (load_grasp_network)'),
         ('neural_controller.py', 'predict', '- forward pass (predict)')]


def per_pattern(repeats):
    """[(name, nodes, median wall ms, median CPU ms, Jacobians of the closest curve's fits)] for every shape of
    deployment_table.py on its rod #3 at friction 0.5, the default settings (the drag compensation fits twice)."""
    import deployment_table as dt
    from rod_deploy.planning import curvature_rate
    rod = rod_description_from_dict(dict(dt.RODS[3], friction=0.5))
    solve, jacobians = curvature_rate.levenberg_marquardt, [0]

    def counted(residuals, normal_equations, x0, **kw):
        def counting(x, r):
            jacobians[0] += 1
            return normal_equations(x, r)
        return solve(residuals, counting, x0, **kw)

    rows = []
    for name, pts in dt.all_patterns().items():
        plan_trajectory(pts, rod, PlannerSettings())                               # warm
        jacobians[0] = 0
        curvature_rate.levenberg_marquardt = counted
        try:
            plan = plan_trajectory(pts, rod, PlannerSettings())
        finally:
            curvature_rate.levenberg_marquardt = solve
        times, cpu = [], []
        for _ in range(repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            plan_trajectory(pts, rod, PlannerSettings())
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        rows.append((name, len(plan.pattern.s), 1000 * float(np.median(times)), 1000 * float(np.median(cpu)),
                     jacobians[0]))
    return rows


def profile(args, pts, rod, n=20):
    """Per-plan CPU time [ms] of the parts of the default plan (cProfile with the process's CPU clock)."""
    import cProfile
    import pstats
    plan_trajectory(pts, rod, PlannerSettings())
    pr = cProfile.Profile(time.process_time)
    c0 = time.process_time()
    pr.enable()
    for _ in range(n):
        plan_trajectory(pts, rod, PlannerSettings())
    pr.disable()
    total = time.process_time() - c0
    stats = pstats.Stats(pr).stats
    rows = []
    for file, func, what in PARTS:
        hits = [(v[1], v[3]) for (f, _, name), v in stats.items() if f.endswith(file) and name == func]
        rows.append((what, sum(h[0] for h in hits) / n, 1000 * sum(h[1] for h in hits) / n))
    lines = ['# Where the default plan\'s CPU time goes (`python benchmarks/planning_speed.py --profile`)', '',
             f'The 200-node spiral of planning_speed.md, the default settings; cProfile with the process\'s CPU clock '
             f'(all threads) over {n} plans, per plan (profiling adds its own overhead); load average '
             f'{os.getloadavg()[0]:.1f}, OPENBLAS_NUM_THREADS {os.environ.get("OPENBLAS_NUM_THREADS", "unset")}. '
             f'Total {1000 * total / n:.1f} ms CPU per plan.', '', '| part | calls per plan | CPU ms per plan |',
             '|---|---|---|'] + [f'| {a} | {b:.1f} | {c:.1f} |' for a, b, c in rows]
    out = results_path(args, 'planning_speed_profile.md')
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--repeats', type=int, default=20)
    ap.add_argument('--profile', action='store_true', help='where the default plan\'s CPU time goes, instead')
    add_results_argument(ap)
    args = ap.parse_args()
    rod = rod_description_from_dict({'length': 1.2, 'radius': 0.002, 'L_gb': 0.034})
    pts = spiral()
    if args.profile:
        return profile(args, pts, rod)
    rows = []
    load_start = os.getloadavg()[0]
    default_start = PlannerSettings().start
    for method, start in (('nn', default_start), ('nn', 'tangent'), ('intuitive', default_start)):
        settings = PlannerSettings(method=method, start=start)
        plan_trajectory(pts, rod, settings)                                      # warm (imports, weights)
        times, cpu = [], []
        for _ in range(args.repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            plan = plan_trajectory(pts, rod, settings)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        label = method if method == 'intuitive' else f'{method}, {start} start'
        rows.append((f'in-process, {label}', len(plan.pattern.s), 1000 * float(np.median(times)),
                     1000 * float(np.median(cpu))))
    t0, c0 = time.perf_counter(), time.process_time()
    plan_trajectory(pts[:60], rod, PlannerSettings(method='numeric'))
    rows.append(('in-process, numeric (60 nodes)', 60, 1000 * (time.perf_counter() - t0),
                 1000 * (time.process_time() - c0)))
    with tempfile.TemporaryDirectory() as d:
        np.savetxt(Path(d) / 'p.txt', pts)
        (Path(d) / 'rod.yaml').write_text('length: 1.2\nradius: 0.002\nL_gb: 0.034\n')
        times, cpu = [], []
        for _ in range(max(3, args.repeats // 4)):
            t0, c0 = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run([str(Path(sys.executable).parent / 'rod-deploy'), 'plan', '--pattern', str(Path(d) / 'p.txt'),
                            '--rod', str(Path(d) / 'rod.yaml'), '--out', str(Path(d) / 't.csv')], check=True,
                           capture_output=True)
            times.append(time.perf_counter() - t0)
            c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu.append(c1.ru_utime + c1.ru_stime - c0.ru_utime - c0.ru_stime)
        rows.append((f'whole `rod-deploy plan` process, nn, {default_start} start', len(plan.pattern.s),
                     1000 * float(np.median(times)), 1000 * float(np.median(cpu))))
    lines = ['# Planning speed (`python benchmarks/planning_speed.py`)', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} (at the end; '
             f'{load_start:.1f} at the start), OPENBLAS_NUM_THREADS {os.environ.get("OPENBLAS_NUM_THREADS", "unset")}; '
             f'a 200-node spiral (5 mm steps, starting on a bend of radius 15 cm), rod L_gb 3.4 cm; the planner\'s '
             f'default start: {default_start}; medians of {args.repeats} runs (targets: 50 ms '
             'in-process with the network, 5 s for the whole process; the paper: about 0.4 s).', '',
             'CPU ms: the process\'s CPU time (time.process_time, all threads; for the whole process the child\'s user '
             '+ system time), less sensitive to the load than the wall clock.', '', '| what | nodes | median ms | median CPU ms |', '|---|---|---|---|'] + [
        f'| {a} | {b} | {c:.1f} | {"" if d is None else f"{d:.1f}"} |' for a, b, c, d in rows]
    shapes = per_pattern(max(3, args.repeats // 4))
    lines += ['', f'Every shape of the deployment table as drawn (`deployment_table.py`: rod #3, friction 0.5, the '
              f'default settings; medians of {max(3, args.repeats // 4)} runs; Jacobians: those the closest curve\'s '
              f'fits formed in one plan):', '', '| shape | nodes | median ms | median CPU ms | Jacobians |',
              '|---|---|---|---|---|'] + [f'| {a} | {b} | {c:.1f} | {d:.1f} | {e} |' for a, b, c, d, e in shapes]
    cpu = np.array([r[3] for r in shapes])
    lines += ['', f'CPU per plan over the {len(shapes)} shapes: median {np.median(cpu):.1f} ms, largest '
              f'{cpu.max():.1f} ms ({shapes[int(np.argmax(cpu))][0]}).']
    out = results_path(args, 'planning_speed.md')
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
