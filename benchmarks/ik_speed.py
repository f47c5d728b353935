"""Benchmark: arm-command bridge, IK + time parameterisation along deployment-like gripper paths (Baxter right arm).

Target (issue 11): IK along a 200-pose deployment path <= 0.5 s; position tracking error <= 0.1 mm where reachable.
Paths (table frame, default table pose of the bridge):
  * synthetic deployment-like paths (robot_bridge.kinematics.example_paths): 200 poses over 20 s, the gripper circling
    0.3-0.9 m above the table while tilting by up to 60 deg;
  * the released planner's gripper trajectories (../shared/reference/rod_deployment/reference_outputs/*_traj_NN.txt,
    read in place, not shipped; 102-195 poses, no stamps: 0.1 s apart), when present.
Each is planned ``--repeat`` times with the model built once; medians. Usage:
    python benchmarks/ik_speed.py [--repeat 5] [--out benchmarks/results/ik_speed.md]
"""
import argparse
import glob
import json
import os
import platform
import statistics
import time

import numpy as np

from robot_bridge.kinematics.example_paths import deployment_like_path
from robot_bridge.kinematics.gripper_path import GripperPath, PathRejected
from robot_bridge.kinematics.planner import ArmCommandPlanner, BridgeConfig

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REFERENCE = os.path.join(os.path.dirname(ROOT), 'shared', 'reference', 'rod_deployment', 'reference_outputs')


def paths():
    out = [('deployment-like, r 0.15 m, 0.3-0.9 m, 60 deg (default)', deployment_like_path()),
           ('deployment-like, r 0.10 m, 0.3-0.9 m, 60 deg', deployment_like_path(radius_m=0.10)),
           ('deployment-like, r 0.20 m, 0.3-0.9 m, 60 deg', deployment_like_path(radius_m=0.20)),
           ('deployment-like, r 0.20 m, 0.3-0.6 m, 60 deg', deployment_like_path(radius_m=0.20, height_m=(0.3, 0.6))),
           ('deployment-like, r 0.15 m, 0.3-0.9 m, 60 deg, 2 turns', deployment_like_path(turns=2.0))]
    for f in sorted(glob.glob(os.path.join(REFERENCE, '*_traj_NN.txt'))):
        d = np.loadtxt(f, comments='#')
        out.append((f'released planner: {os.path.basename(f)[:-12]} ({len(d)} poses)',
                    GripperPath(0.1 * np.arange(len(d)), d[:, :3], d[:, 3:7])))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--repeat', type=int, default=5)
    ap.add_argument('--out', default=os.path.join(ROOT, 'benchmarks', 'results', 'ik_speed.md'))
    a = ap.parse_args()
    t0 = time.perf_counter()
    planner = ArmCommandPlanner(BridgeConfig())
    build_s = time.perf_counter() - t0
    rows, results = [], []
    for name, path in paths():
        times, ik_times, plan, error = [], [], None, None
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            try:
                plan = planner.plan(path)
            except PathRejected as exc:
                error = str(exc)
                break
            times.append(time.perf_counter() - t0)
            ik_times.append(plan.wall_time_s['ik'])
        if error:
            rows.append(f'| {name} | {len(path)} | rejected: {error} | | | | | |')
            results.append({'path': name, 'poses': len(path), 'rejected': error})
            continue
        s = plan.summary()
        r = {'path': name, 'poses': len(path), 'plan_s': statistics.median(times),
             'ik_s': statistics.median(ik_times), **{k: s[k] for k in (
                 'position_max_m', 'position_rms_m', 'orientation_max_rad', 'orientation_rms_rad',
                 'between_poses_max_m', 'time_scale', 'ik_iterations_mean')}}
        results.append(r)
        rows.append(f'| {name} | {len(path)} | {r["ik_s"]:.3f} | {r["plan_s"]:.3f} | {r["position_max_m"] * 1e3:.5f} / '
                    f'{r["position_rms_m"] * 1e3:.5f} | {np.degrees(r["orientation_max_rad"]):.5f} | '
                    f'{r["between_poses_max_m"] * 1e3:.2f} | {r["time_scale"]:.2f} | {r["ik_iterations_mean"]:.1f} |')
    lines = [
        '# Arm-command bridge: IK speed and accuracy along deployment paths',
        '',
        f'Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores (shared with other jobs: '
        f'timings are noisy), Python {platform.python_version()}; medians of {a.repeat} runs. Produced by '
        '`python benchmarks/ik_speed.py`. Baxter right arm (project URDF), default table pose and grasp offset; '
        f'Pinocchio model built once ({build_s:.3f} s).',
        '',
        'Targets: IK along a 200-pose deployment path <= 0.5 s; position error <= 0.1 mm where reachable.',
        '',
        '| path | poses | IK [s] | IK + timing + checks [s] | position error max / RMS [mm] | orientation max [deg] '
        '| midway between poses, max [mm] | time scale | IK iterations / pose |',
        '|---|---|---|---|---|---|---|---|---|',
        *rows,
        '',
        '"midway between poses": the gripper of the interpolated joint trajectory, halfway in time between two poses, '
        'against the midpoint of the straight segment joining them (not an IK error: the path itself is only given at '
        'its poses). "time scale": 1 = the path\'s stamps kept; > 1 = slowed down uniformly to respect the joint '
        'velocity/acceleration limits (URDF velocity limits; acceleration = velocity limit / 0.5 s). The released '
        'planner\'s trajectories carry no stamps; 0.1 s per pose is assumed.',
    ]
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, 'w') as f:
        f.write('\n'.join(lines) + '\n')
    with open(a.out[:-3] + '.json', 'w') as f:
        json.dump({'model_build_s': build_s, 'results': results}, f, indent=2)
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
