"""Speed of the DER deployment simulator, before vs after, side by side in the same run.

    python benchmarks/der_speed.py [--patterns circle,letterC] [--shape-patterns letterU] [--repeats 3]
                                   [--baseline COMMIT] [--commit-results]

A full deployment of the paper's rod #3 (0.89 m, 5 mm edges, dt 0.02 s, gripper at 0.01 m/s, medium friction 0.5)
along our network planner's trajectory, for each pattern (the paper's, read in place from
``../shared/reference/rod_deployment/patterns`` when present, else ours drawn in ``deployment_table.py``). The
trajectory is planned once here (the published patterns are looked for where ``deployment_table.py`` looks:
``ROD_DEPLOYMENT_REFERENCE`` overrides; without them the defaults are our spiral, digit 2 and letter S); each
simulation runs in its own Python process (``simulate_deployment`` only), once with this checkout's ``rod_deploy`` ("after") and once with the ``--baseline`` commit's (default: the last
commit with the numpy simulator), extracted with ``git archive`` into ``out/der_speed_baseline/`` ("before"),
alternately, so both see the same machine load. Per run: CPU time (user + system of the process during the
simulation: what the load of other processes does not inflate), wall time, the 1-minute load average, Newton
iterations. Reported: medians over ``--repeats`` and, per pattern, the largest distance between the final nodes of
the two versions and their Eq. 17 e_mean. ``--shape-patterns``: more patterns simulated once per version, for the
shape comparison only. Numba's first compile (kernels not yet in ``__pycache__``) is measured apart, in a process
with an empty ``NUMBA_CACHE_DIR``.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from deployment_table import REF, RODS, all_patterns
from results_dir import ROOT, add_results_argument, results_path

#: the last commit whose simulator assembled the DER forces with numpy (before the numba kernels)
DEFAULT_BASELINE = '2dbe0b4'
PACKAGES = ('rod_deploy', 'flex_ident', 'robot_bridge')


def _pythonpath(src: Path) -> str:
    return os.pathsep.join(str(src / p) for p in PACKAGES)


def baseline_tree(commit: str) -> Path:
    """ros_ws/src of ``commit``, extracted once into out/der_speed_baseline/<sha> (no git state is changed)."""
    sha = subprocess.run(['git', '-C', str(ROOT), 'rev-parse', '--short', commit], check=True, capture_output=True,
                         text=True).stdout.strip()
    dest = ROOT / 'out' / 'der_speed_baseline' / sha
    if not (dest / 'ros_ws' / 'src' / 'rod_deploy').exists():
        dest.mkdir(parents=True, exist_ok=True)
        archive = subprocess.run(['git', '-C', str(ROOT), 'archive', sha, 'ros_ws/src'], check=True,
                                 capture_output=True).stdout
        subprocess.run(['tar', '-x', '-C', str(dest)], input=archive, check=True)
    return dest / 'ros_ws' / 'src'


def worker(plan_file: str, out_file: str):
    """Simulate the planned deployment with whatever rod_deploy is on the path; write timings and the result."""
    from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment
    from rod_deploy.planning.rod_description import rod_description_from_dict
    d = np.load(plan_file)
    rod = rod_description_from_dict(json.loads(str(d['rod'])))
    load0 = os.getloadavg()[0]
    c0, w0 = time.process_time(), time.perf_counter()
    res = simulate_deployment(d['t'], d['position'], d['quaternion'], rod, SimulationSettings(friction=0.5))
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    np.savez(out_file, nodes=res.nodes, deployed_xy=res.deployed_xy, cpu_s=cpu, wall_s=wall,
             load=0.5 * (load0 + os.getloadavg()[0]), steps=res.steps, newton=res.newton_iterations)


def profile_worker(out_file: str):
    """cProfile of a short deployment (rod #3's material, 0.3 m long, a quarter circle of radius 8 cm) with whatever
    rod_deploy is on the path: CPU time, Newton iterations and the 15 functions with the most own time."""
    import cProfile
    import io
    import pstats
    from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory
    rod = rod_description_from_dict(dict(RODS[3], length=0.3, friction=0.5))
    th = np.linspace(0, np.pi / 2, 100)
    plan = plan_trajectory(np.column_stack([0.08 * np.sin(th), 0.08 * (1 - np.cos(th))]), rod, PlannerSettings())
    prof = cProfile.Profile()
    c0 = time.process_time()
    prof.enable()
    res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod, SimulationSettings(friction=0.5))
    prof.disable()
    cpu = time.process_time() - c0
    text = io.StringIO()
    pstats.Stats(prof, stream=text).sort_stats('tottime').print_stats(15)
    table = [ln for ln in text.getvalue().splitlines() if ln.strip() and ln.strip()[0].isdigit() and '/' in ln]
    Path(out_file).write_text(json.dumps({'cpu_s': cpu, 'steps': res.steps, 'newton': res.newton_iterations,
                                          'edges': len(res.nodes) - 1, 'table': table}))


def run(src: Path, args: list, out: Path, cwd: Path):
    env = dict(os.environ, PYTHONPATH=_pythonpath(src), OMP_NUM_THREADS='1', OPENBLAS_NUM_THREADS='1')
    subprocess.run([sys.executable, __file__, *args, str(out)], check=True, env=env, cwd=str(cwd))


def run_deployment(src: Path, plan_file: Path, tmp: Path, tag: str) -> dict:
    out = tmp / f'{tag}.npz'
    run(src, ['--worker', str(plan_file)], out, tmp)
    r = np.load(out)
    return {k: r[k] for k in r.files}


def profile(versions, args):
    """der_profile.md: the short deployment profiled with each version (in its own process)."""
    lines = ['# Where a DER deployment spends its time (`python benchmarks/der_speed.py --profile`)', '',
             'cProfile of a short deployment: rod #3\'s material, 0.3 m long (60 edges of 5 mm), a quarter circle '
             'of radius 8 cm planned by the network planner, dt 0.02 s, 0.01 m/s, friction 0.5, each version in '
             'its own process (the profiler roughly doubles the CPU time of Python-heavy code). `tottime`: own '
             'time of the function, `cumtime`: with what it calls (seconds, wall clock of a shared machine).', '']
    with tempfile.TemporaryDirectory() as tmpd:
        for v, src in versions.items():
            out = Path(tmpd) / f'{v}.json'
            run(src, ['--profile-worker'], out, Path(tmpd))
            r = json.loads(out.read_text())
            lines += [f'## {v} ({"commit " + args.baseline if v == "before" else "this checkout"})', '',
                      f'{r["steps"]} steps, {r["newton"]} Newton iterations ({r["newton"] / r["steps"]:.2f} per '
                      f'step), {r["cpu_s"]:.1f} s CPU under the profiler: {1e3 * r["cpu_s"] / r["newton"]:.2f} ms '
                      'per Newton iteration (everything included).', '', '```',
                      '   ncalls  tottime  percall  cumtime  percall filename:lineno(function)',
                      *[ln.replace(str(src), '').replace(sys.prefix, '<venv>') for ln in r['table']], '```', '']
    out = results_path(args, 'der_profile.md')
    out.write_text('\n'.join(lines))
    print(out.read_text())


def compile_cost(src: Path, tmp: Path) -> float:
    """CPU seconds of the first numba compile: a tiny deployment step in a process with an empty kernel cache,
    minus the same with the cache filled."""
    code = ('import time; c = time.process_time()\n'
            'from rod_deploy.physics.der_simulator import DiscreteElasticRod, RodParameters\n'
            'import numpy as np\n'
            'x = np.c_[np.linspace(0, 0.1, 11), np.zeros(11), np.full(11, 0.002)]\n'
            'r = DiscreteElasticRod(x, RodParameters(EI=1e-4, EA=10.0, GJ=1e-4, rho_A=0.01, radius=0.002, '
            'table=True, friction=0.5))\n'
            'r.clamp_node(-1); r.step(0.02); r.static_solve(max_iter=2)\n'
            'from rod_deploy.physics.reference_frames import signed_angle\n'
            'signed_angle(x[1], x[2], x[3])\n'
            'print(time.process_time() - c)')
    cache = tmp / 'numba_cache'
    env = dict(os.environ, PYTHONPATH=_pythonpath(src), NUMBA_CACHE_DIR=str(cache))
    cold = float(subprocess.run([sys.executable, '-c', code], env=env, check=True, capture_output=True,
                                text=True).stdout)
    warm = float(subprocess.run([sys.executable, '-c', code], env=env, check=True, capture_output=True,
                                text=True).stdout)
    return cold - warm


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    published = (REF / 'patterns').exists()     # else shapes of our own (deployment_table.own_patterns)
    ap.add_argument('--patterns', default='circle,letterC' if published else 'spiral,digit2',
                    help='timed patterns (medians over --repeats)')
    ap.add_argument('--shape-patterns', default='letterU' if published else 'letterS',
                    help='patterns simulated once per version, for the shape comparison only ("" for none)')
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--baseline', default=DEFAULT_BASELINE, help='git commit of the "before" simulator')
    add_results_argument(ap)
    ap.add_argument('--profile', action='store_true', help='profile a short deployment with each version instead '
                    '(writes der_profile.md)')
    ap.add_argument('--worker', nargs=2, help=argparse.SUPPRESS)
    ap.add_argument('--profile-worker', nargs=1, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        return worker(*args.worker)
    if args.profile_worker:
        return profile_worker(*args.profile_worker)
    if args.repeats < 1:
        sys.exit('der_speed.py: error: --repeats must be at least 1')
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory
    timed = [p for p in args.patterns.split(',') if p]
    shape_only = [p for p in args.shape_patterns.split(',') if p and p not in timed]
    patterns = all_patterns(','.join(timed + shape_only))
    missing = [p for p in timed + shape_only if p not in patterns]
    if missing:
        sys.exit(f'der_speed.py: error: unknown pattern(s) {", ".join(missing)}')
    versions = {'before': baseline_tree(args.baseline), 'after': ROOT / 'ros_ws' / 'src'}
    if args.profile:
        return profile(versions, args)
    rod_dict = dict(RODS[3], friction=0.5)
    rod = rod_description_from_dict(rod_dict)
    out = results_path(args, 'der_speed.md')
    t_all = time.perf_counter()
    rows = {}
    with tempfile.TemporaryDirectory() as tmpd:
        tmp = Path(tmpd)
        compile_s = compile_cost(versions['after'], tmp)
        print(f'numba first compile: {compile_s:.1f} s CPU', flush=True)
        for name in timed + shape_only:
            plan = plan_trajectory(patterns[name], rod, PlannerSettings(method='nn'))
            plan_file = tmp / f'plan_{name}.npz'
            np.savez(plan_file, t=plan.t, position=plan.position, quaternion=plan.quaternion,
                     rod=json.dumps(rod_dict))
            runs = {'before': [], 'after': []}
            for k in range(args.repeats if name in timed else 1):
                for v in (('before', 'after') if k % 2 == 0 else ('after', 'before')):
                    r = run_deployment(versions[v], plan_file, tmp, f'{name}_{v}_{k}')
                    runs[v].append(r)
                    print(f'{name:10s} {v:6s} run {k + 1}: CPU {float(r["cpu_s"]):6.1f} s, wall '
                          f'{float(r["wall_s"]):6.1f} s, load {float(r["load"]):4.1f}, {int(r["steps"])} steps, '
                          f'{int(r["newton"])} Newton iterations', flush=True)
            e = {v: eq17_error(patterns[name], runs[v][0]['deployed_xy'])['e_mean_cm'] for v in runs}
            dist = float(np.max(np.linalg.norm(runs['before'][0]['nodes'] - runs['after'][0]['nodes'], axis=1)))
            rows[name] = (name in timed, runs, e, dist)
            write(out, rows, compile_s, args, time.perf_counter() - t_all)
    print(out.read_text())
    print(f'results: {out}')


def _median(runs, key):
    return float(np.median([float(r[key]) for r in runs]))


def write(out, rows, compile_s, args, total_s):
    lines = ['# DER deployment simulator speed, before vs after (`python benchmarks/der_speed.py`)', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores, shared (other processes running: the load '
             'average is the 1-minute one during each simulation, so wall times are upper bounds; CPU time is the '
             f'comparable number). {total_s:.0f} s in all. Rod #3 (0.89 m, h 2 mm, L_gb 3.4 cm), 5 mm edges '
             '(178), dt 0.02 s, gripper at 0.01 m/s, friction 0.5, the network planner\'s trajectory. Before: '
             f'commit {args.baseline} (numpy assembly); after: this checkout (numba kernels). Each simulation in '
             'its own process, before and after alternating; medians over the runs.', '',
             f'Numba\'s first compile of the kernels (empty cache): {compile_s:.1f} s CPU, once per checkout '
             '(cached in `__pycache__` afterwards; loading the cache is part of the "after" times below).', '',
             '| pattern | runs | CPU s before | CPU s after | CPU speed-up | wall s before | wall s after | '
             'load | Newton iterations before / after |',
             '|---|---|---|---|---|---|---|---|---|']
    for name, (is_timed, runs, e, dist) in rows.items():
        if not is_timed:
            continue
        cb, ca = _median(runs['before'], 'cpu_s'), _median(runs['after'], 'cpu_s')
        loads = [float(r['load']) for v in runs for r in runs[v]]
        lines.append(f'| {name} | {len(runs["after"])} | {cb:.1f} | {ca:.1f} | {cb / ca:.1f}x | '
                     f'{_median(runs["before"], "wall_s"):.1f} | {_median(runs["after"], "wall_s"):.1f} | '
                     f'{min(loads):.1f}-{max(loads):.1f} | {int(runs["before"][0]["newton"])} / '
                     f'{int(runs["after"][0]["newton"])} |')
    lines += ['', 'Deployed shapes, before vs after (first run of each):', '',
              '| pattern | max distance between final nodes | e_mean cm before | e_mean cm after |',
              '|---|---|---|---|']
    for name, (_, runs, e, dist) in rows.items():
        lines.append(f'| {name} | {dist:.2e} m | {e["before"]:.4f} | {e["after"]:.4f} |')
    out.write_text('\n'.join(lines) + '\n')


if __name__ == '__main__':
    main()
