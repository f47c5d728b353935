"""robot-bridge: the arm-command bridge without ROS.

  robot-bridge plan GRIPPER_CSV --out JOINT_CSV [--urdf U --base-link B --tip-link T --joints J ...]
      [--table-xyz X Y Z --table-rpy R P Y --grasp-xyz X Y Z --grasp-rpy R P Y]
      [--velocity-scaling S --acceleration-scaling S] [--json]

Reads a gripper trajectory (CONTRACTS.md section 4, table frame), solves IK along it for the arm (Baxter's right arm
by default), time-parameterises it under the joint limits and writes the joint trajectory as CSV
(``t,<joint>...,<joint>_vel...,<joint>_acc...``; s, rad, rad/s, rad/s^2). A path the arm cannot follow is rejected
with the first bad pose named (exit status 2, nothing written).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from robot_bridge.kinematics.gripper_path import read_gripper_csv
from robot_bridge.kinematics.planner import ArmCommandPlanner, BridgeConfig, JointPlan

PROG = 'robot-bridge'


def write_joint_csv(path: str | Path, plan: JointPlan):
    tr, names = plan.trajectory, plan.joint_names
    header = ['t'] + names + [f'{n}_vel' for n in names] + [f'{n}_acc' for n in names]
    np.savetxt(path, np.column_stack([tr.t_s, tr.q, tr.qd, tr.qdd]), delimiter=',', header=','.join(header),
               comments='', fmt='%.10g')


def _parser() -> argparse.ArgumentParser:
    d = BridgeConfig()
    p = argparse.ArgumentParser(prog=PROG, description='Gripper trajectory (table frame) -> joint trajectory.')
    sub = p.add_subparsers(dest='command', required=True)
    plan = sub.add_parser('plan', help='IK + time parameterisation of a gripper trajectory CSV')
    plan.add_argument('gripper_csv', help='CSV t,x,y,z,qx,qy,qz,qw (CONTRACTS.md section 4)')
    plan.add_argument('--out', required=True, help='joint trajectory CSV to write')
    plan.add_argument('--urdf', default='', help='arm URDF (default: the project\'s Baxter right arm)')
    plan.add_argument('--base-link', default=d.base_link)
    plan.add_argument('--tip-link', default=d.tip_link)
    plan.add_argument('--joints', nargs='+', default=d.joints, help='the arm joints, base to tip')
    for name, default, unit in (('table-xyz', d.table_xyz, 'm'), ('table-rpy', d.table_rpy, 'rad'),
                                ('grasp-xyz', d.grasp_xyz, 'm'), ('grasp-rpy', d.grasp_rpy, 'rad')):
        plan.add_argument(f'--{name}', nargs=3, type=float, default=list(default), metavar=('A', 'B', 'C'),
                          help=f'[{unit}] (default ' + ' '.join(f'{v:.6g}' for v in default) + ')')
    plan.add_argument('--velocity-scaling', type=float, default=1.0, help='fraction of the velocity limits')
    plan.add_argument('--acceleration-scaling', type=float, default=1.0, help='fraction of the acceleration limits')
    plan.add_argument('--json', action='store_true', help='print the summary as JSON')
    return p


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        config = BridgeConfig(urdf=args.urdf, base_link=args.base_link, tip_link=args.tip_link,
                              joints=list(args.joints), table_xyz=tuple(args.table_xyz),
                              table_rpy=tuple(args.table_rpy), grasp_xyz=tuple(args.grasp_xyz),
                              grasp_rpy=tuple(args.grasp_rpy), velocity_scaling=args.velocity_scaling,
                              acceleration_scaling=args.acceleration_scaling)
        plan = ArmCommandPlanner(config).plan(read_gripper_csv(args.gripper_csv))
    except ValueError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    write_joint_csv(args.out, plan)
    summary = plan.summary()
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f'{args.out}: {summary["poses"]} poses, {summary["duration_s"]:.2f} s; {summary["timing"]}\n'
              f'IK tracking error: position max {summary["position_max_m"] * 1e3:.3g} mm, '
              f'RMS {summary["position_rms_m"] * 1e3:.3g} mm; orientation max '
              f'{np.degrees(summary["orientation_max_rad"]):.3g} deg, RMS '
              f'{np.degrees(summary["orientation_rms_rad"]):.3g} deg; midway between poses '
              f'{summary["between_poses_max_m"] * 1e3:.2f} mm; IK {summary["wall_time_s"]["ik"]:.3f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
