"""Small example systems for tests, benchmarks and documentation.

* :func:`spatial_arm_urdf`: a URDF of a 3-joint spatial arm (revolute, continuous, fixed joints; full, off-diagonal
  inertia tensors; declared damping) whose links are also loadable by MuJoCo's URDF importer;
* :func:`hanging_loop_model`: the contract loop hanging from a fixed grasp frame (no arm), clamped below (a
  conservative constrained system: 2N coordinates, 12 constraints);
* :func:`experiment_yaml`: an experiment file for the project's Baxter URDF and the contract loop.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .loop_geometry import add_contract_loop
from .model import ModelBuilder
from .rigid_body import trans

SPATIAL_ARM_URDF = """<?xml version="1.0"?>
<robot name="spatial_arm">
  <link name="base"/>
  <link name="l1">
    <inertial><origin xyz="0.01 0.02 0.15" rpy="0.1 0 0.2"/><mass value="2.0"/>
      <inertia ixx="0.030" ixy="0.002" ixz="-0.001" iyy="0.025" iyz="0.003" izz="0.010"/></inertial>
  </link>
  <link name="l2">
    <inertial><origin xyz="0.12 0.0 0.01" rpy="0 0.3 0"/><mass value="1.5"/>
      <inertia ixx="0.004" ixy="-0.0005" ixz="0.0008" iyy="0.020" iyz="0.0002" izz="0.018"/></inertial>
  </link>
  <link name="l3">
    <inertial><origin xyz="0.05 0.01 -0.02" rpy="0 0 0"/><mass value="0.8"/>
      <inertia ixx="0.002" ixy="0.0001" ixz="0.0" iyy="0.003" iyz="-0.0002" izz="0.0025"/></inertial>
  </link>
  <link name="tool">
    <inertial><origin xyz="0 0 0.03" rpy="0 0 0"/><mass value="0.3"/>
      <inertia ixx="0.0004" ixy="0" ixz="0" iyy="0.0004" iyz="0" izz="0.0002"/></inertial>
  </link>
  <link name="tip"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/><origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-10" upper="10" effort="50" velocity="2"/><dynamics damping="{damping}"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="l1"/><child link="l2"/><origin xyz="0 0.05 0.3" rpy="-1.5707963 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-10" upper="10" effort="50" velocity="2"/><dynamics damping="{damping}"/>
  </joint>
  <joint name="j3" type="continuous">
    <parent link="l2"/><child link="l3"/><origin xyz="0.25 0 0" rpy="0.3 0.2 0.1"/><axis xyz="0.6 0 0.8"/>
    <dynamics damping="{damping}"/>
  </joint>
  <joint name="tool_mount" type="fixed">
    <parent link="l3"/><child link="tool"/><origin xyz="0.1 0 0" rpy="0 1.5707963 0"/>
  </joint>
  <joint name="tip_joint" type="fixed">
    <parent link="tool"/><child link="tip"/><origin xyz="0 0 0.06" rpy="0 0 0"/>
  </joint>
</robot>
"""


def spatial_arm_urdf(path, damping: float = 0.0) -> Path:
    """Write the 3-joint spatial arm URDF (joints j1, j2, j3; base_link 'base', tip_link 'tip')."""
    path = Path(path)
    path.write_text(SPATIAL_ARM_URDF.replace('{damping}', repr(float(damping))))
    return path


def hanging_loop_model(n_links: int = 6, radius_m: float = 0.25, mass_kg: float = 0.6, tube_radius_m: float = 0.02,
                       k_theta: float = 2.0, k_phi: float = 1.5, clamp_offset_m=(0.0, 0.0, 0.0),
                       gravity=(0.0, 0.0, -9.81)):
    """The contract loop below a fixed grasp frame G (gripper pointing down, at the base origin), clamped at
    C = G T(0, 0, 2R) + clamp_offset (base frame). No arm: every coordinate is a loop angle."""
    builder = ModelBuilder(gravity=gravity)
    G = np.diag([1.0, -1.0, -1.0, 1.0])               # rotation by pi about x: z_G points down
    C = G @ trans(0.0, 0.0, 2.0 * radius_m)
    C[:3, 3] += np.asarray(clamp_offset_m, float)
    add_contract_loop(builder, n_links, radius_m, mass_kg, tube_radius_m, grasp_coord=-1, grasp_offset=G,
                      clamp_pose=C, k_theta=k_theta, k_phi=k_phi)
    builder.add_frame('ee', -1, G)
    return builder.build()


def experiment_yaml(path, urdf_path, n_links: int = 12, clamp_xyz=(0.6, -0.8, -0.3),
                    clamp_rpy=(math.pi, 0.0, 0.75 * math.pi), parameters=None, window=None, extra: str = '') -> Path:
    """Write an experiment YAML for the Baxter right arm (joint names of the project's URDF) and the loop."""
    params = parameters or {'k_theta': (1.0, 0.001, 1000.0), 'k_phi': (1.0, 0.001, 1000.0)}
    lines = [
        'arm:',
        f'  urdf: {urdf_path}',
        '  base_link: base',
        '  tip_link: right_gripper',
        '  joints: [right_s0, right_s1, right_e0, right_e1, right_w0, right_w1, right_w2]',
        'object:',
        '  type: loop',
        f'  links: {n_links}',
        '  radius: 0.25',
        '  mass: 0.6',
        '  tube_radius: 0.02',
        '  grasp: {xyz: [0, 0, 0], rpy: [0, 0, 0]}',
        f'  clamp: {{xyz: {list(clamp_xyz)}, rpy: {list(clamp_rpy)}}}',
        'identify:',
        '  parameters:',
    ]
    for name, (initial, lo, hi) in params.items():
        lines.append(f'    {name}: {{initial: {initial}, min: {lo}, max: {hi}}}')
    if window is not None:
        lines.append(f'  window: {list(window)}')
    path = Path(path)
    path.write_text('\n'.join(lines) + '\n' + extra)
    return path
