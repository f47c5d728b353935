"""What the drag compensation costs at plan time: CPU time of ``plan_trajectory`` with and without it (rod #3,
friction 0.5, the paper's 7 patterns and ours; median of 3 each, one thread), and of a whole ``rod-deploy plan``
process on the letter A (CPU time of the child process: imports, network load, planning, CSV).

    OMP_NUM_THREADS=1 PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/drag_compensation_cost.py \
        [--commit-results]
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main():
    from deployment_table import REF, RODS, all_patterns
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    add_results_argument(ap)
    args = ap.parse_args()
    rod = rod_description_from_dict(RODS[3])
    patterns = all_patterns('all')
    plan_trajectory(patterns['letterA'], rod, PlannerSettings())             # warm-up (network load, imports)
    rows = []
    for name, P in patterns.items():
        cpu = {}
        for comp in (False, True):
            ts = []
            for _ in range(3):
                c = time.process_time()
                plan_trajectory(P, rod, PlannerSettings(friction=0.5, drag_compensation=comp))
                ts.append(time.process_time() - c)
            cpu[comp] = float(np.median(ts))
        rows.append((name, cpu[False], cpu[True]))
    # a whole rod-deploy plan process (its children's CPU time)
    with tempfile.TemporaryDirectory() as d:
        rod_file = Path(d) / 'rod3.yaml'
        rod_file.write_text('length: 0.89\nradius: 0.002\nL_gb: 0.034\nfriction: 0.5\n')
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, '-m', 'rod_deploy.cli.main', 'plan', '--pattern',
                        str(REF / 'patterns' / 'letterA.txt'), '--rod', str(rod_file), '--out',
                        str(Path(d) / 'a.csv')], check=True, capture_output=True,
                       env={**os.environ, 'PYTHONPATH': str(ROOT / 'ros_ws' / 'src' / 'rod_deploy')})
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        proc_cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    lines = ['# Drag compensation at plan time, `python benchmarks/drag_compensation_cost.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{os.getloadavg()[0]:.1f} at the end: wall times are not meaningful, CPU times are). Rod #3, friction '
             '0.5, planner nn (closest planned curve); CPU time of `plan_trajectory`, median of 3.', '',
             '| pattern | CPU s without | CPU s with | ratio |', '|---|---|---|---|']
    for name, a, b in rows:
        lines.append(f'| {name} | {a:.3f} | {b:.3f} | {b / a:.1f} |')
    a = np.array([r[1] for r in rows])
    b = np.array([r[2] for r in rows])
    lines += ['', f'Median over the patterns {np.median(a):.3f} -> {np.median(b):.3f} s, largest {a.max():.3f} -> '
              f'{b.max():.3f} s. A whole `rod-deploy plan` process on the letter A (compensation on): CPU '
              f'{proc_cpu:.2f} s (wall {wall:.1f} s under this load).']
    out = results_path(args, 'drag_compensation_cost.md')
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
