"""Gripper path (table frame) -> timed joint trajectory of a serial arm, or a rejection naming the first bad pose.

Steps: validate the path (empty, NaN, non-unit quaternion, non-increasing stamps); place it in the robot's base frame
(T_base_gripper = T_base_table T_table_gripper, the table pose a parameter); IK along it (``ik``); time
parameterisation under the joint limits (``timing``); tracking error of the IK solution at every pose, and of the
interpolated trajectory midway between poses. Nothing is returned unless every pose passed.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from robot_bridge.geometry import rpy_matrix
from robot_bridge.sim.motion import BAXTER_RIGHT_NOMINAL_RAD

from .arm import BAXTER_RIGHT_JOINTS, ArmKinematics, default_urdf_path
from .gripper_path import GripperPath, PathRejected
from .ik import IKSettings, PathIK
from .timing import LimitViolation, TimedJointTrajectory, time_parameterise

DEFAULT_ACCELERATION_TIME_S = 0.5   # without explicit limits: a joint may reach its top speed in this time
# The default scene (a parameter: set your own): the table origin 0.5 m in front of and 0.5 m to the right of
# Baxter's base frame, 0.7 m below it, its x axis pointing back at the robot. Chosen on a grid of table poses as one
# under which the most test paths are within reach: synthetic deployment paths (gripper 0.3-0.9 m above the table,
# tilting by 60 deg) and the released planner's trajectories for the letters C, L, U and the line
# (benchmarks/ik_speed.py). Its circle and letter A turn the gripper about the rod's axis by more than Baxter's
# wrist roll (right_w2, +-175 deg) allows under any table pose tried.
DEFAULT_TABLE_XYZ_M = (0.5, -0.5, -0.7)
DEFAULT_TABLE_RPY_RAD = (0.0, 0.0, 3.141592653589793)


def pose_matrix(xyz, rpy) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = rpy_matrix(rpy)
    out[:3, 3] = np.asarray(xyz, dtype=float)
    return out


@dataclass
class BridgeConfig:
    """Everything the bridge needs to know about the arm and the scene (SI units, rpy as in URDF).

    table_xyz / table_rpy: the table frame in base_link (default: DEFAULT_TABLE_*). grasp_xyz / grasp_rpy: the
    gripper frame G in tip_link (the default, identity, puts +z_G along Baxter's approach axis: right_gripper's +z
    points out between the fingers).
    velocity_scaling / acceleration_scaling: fractions of the limits to use. acceleration_limits_rad_s2: per joint
    (or one value; empty: the URDF velocity limit / 0.5 s, URDF has no acceleration limits). posture_rad: the
    null-space posture and the IK seed when the arm's state is unknown (empty: Baxter's nominal pose for Baxter's
    joints, else the middle of the limits).
    """
    urdf: str = ''
    base_link: str = 'base'
    tip_link: str = 'right_gripper'
    joints: list[str] = field(default_factory=lambda: list(BAXTER_RIGHT_JOINTS))
    table_xyz: tuple = DEFAULT_TABLE_XYZ_M
    table_rpy: tuple = DEFAULT_TABLE_RPY_RAD
    grasp_xyz: tuple = (0.0, 0.0, 0.0)
    grasp_rpy: tuple = (0.0, 0.0, 0.0)
    velocity_scaling: float = 1.0
    acceleration_scaling: float = 1.0
    acceleration_limits_rad_s2: list[float] = field(default_factory=list)
    posture_rad: list[float] = field(default_factory=list)
    position_tolerance_m: float = 1e-4
    orientation_tolerance_rad: float = 1e-3

    def validate(self):
        for name in ('velocity_scaling', 'acceleration_scaling'):
            value = getattr(self, name)
            if not 0.0 < value <= 1.0:
                raise ValueError(f'{name} must be in (0, 1], got {value}')
        for name in ('table_xyz', 'table_rpy', 'grasp_xyz', 'grasp_rpy'):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.shape != (3,) or not np.all(np.isfinite(value)):
                raise ValueError(f'{name} needs 3 finite numbers, got {list(getattr(self, name))}')
        if not (self.position_tolerance_m > 0 and self.orientation_tolerance_rad > 0):
            raise ValueError('position_tolerance_m and orientation_tolerance_rad must be positive')


@dataclass
class JointPlan:
    """The bridge's answer: joint_names; trajectory (t from the first pose, q, qd, qdd); the IK tracking error at
    the poses and midway between them; timings."""
    joint_names: list[str]
    trajectory: TimedJointTrajectory
    tracking_error: dict
    ik_iterations_mean: float
    wall_time_s: dict

    def summary(self) -> dict:
        tr = self.trajectory
        return {'poses': int(len(tr.t_s)), 'duration_s': float(tr.t_s[-1]), 'time_scale': tr.time_scale,
                'timing': tr.note, 'peak_velocity_ratio': float(tr.peak_velocity_ratio),
                'peak_acceleration_ratio': float(tr.peak_acceleration_ratio), **self.tracking_error,
                'ik_iterations_mean': self.ik_iterations_mean, 'wall_time_s': self.wall_time_s}


class ArmCommandPlanner:
    """The arm model and IK solver built once from a BridgeConfig; ``plan`` for every path."""

    def __init__(self, config: BridgeConfig):
        config.validate()
        self.config = config
        urdf = config.urdf or default_urdf_path()
        self.arm = ArmKinematics(urdf, config.base_link, config.tip_link, config.joints,
                                 pose_matrix(config.grasp_xyz, config.grasp_rpy))
        lim = self.arm.limits
        n = self.arm.nq
        self.table = pose_matrix(config.table_xyz, config.table_rpy)
        acc = np.asarray(config.acceleration_limits_rad_s2, dtype=float)
        if acc.size == 0:
            acc = lim.velocity / DEFAULT_ACCELERATION_TIME_S
        elif acc.size == 1:
            acc = np.full(n, float(acc[0]))
        if acc.shape != (n,) or not np.all(acc > 0):
            raise ValueError(f'acceleration_limits_rad_s2 needs 1 or {n} positive values, got '
                             f'{list(config.acceleration_limits_rad_s2)}')
        self.velocity_limit = lim.velocity * config.velocity_scaling
        self.acceleration_limit = acc * config.acceleration_scaling
        posture = np.asarray(config.posture_rad, dtype=float)
        if posture.size == 0:
            if list(config.joints) == list(BAXTER_RIGHT_JOINTS):
                posture = np.array(BAXTER_RIGHT_NOMINAL_RAD)
            else:
                posture = np.where(np.isfinite(lim.lower) & np.isfinite(lim.upper), 0.5 * (lim.lower + lim.upper),
                                   np.clip(0.0, lim.lower, lim.upper))
        if posture.shape != (n,):
            raise ValueError(f'posture_rad needs {n} values (one per joint), got {posture.size}')
        self.posture = posture
        self.ik = PathIK(self.arm, posture, IKSettings(position_tolerance_m=config.position_tolerance_m,
                                                        orientation_tolerance_rad=config.orientation_tolerance_rad))

    def to_base(self, path: GripperPath) -> np.ndarray:
        """(K, 4, 4) gripper poses in base_link."""
        return self.table @ path.transforms()

    def executed_path(self, t_s, q) -> GripperPath:
        """The gripper path (table frame, CONTRACTS.md section 4) that joint positions q (K, n; e.g. measured joint
        states in the bridge's joint order) at times t_s (K,) put the gripper through: forward kinematics."""
        to_table = np.linalg.inv(self.table)
        poses = np.array([to_table @ self.arm.gripper_pose(qk) for qk in np.atleast_2d(q)])
        return GripperPath.from_transforms(t_s, poses)

    def plan(self, path: GripperPath, q_start=None) -> JointPlan:
        """Plan a validated path from q_start (the arm's current joints; None: the posture). Raises PathRejected."""
        wall = {}
        t0 = time.perf_counter()
        path.validate()
        targets = self.to_base(path)
        seed = self.posture if q_start is None else np.asarray(q_start, dtype=float)
        t1 = time.perf_counter()
        ik = self.ik.solve_path(targets, seed)
        wall['ik'] = time.perf_counter() - t1
        if ik.failure is not None:
            k = ik.failure.index
            raise PathRejected(ik.failure.reason, k, path.t_s[k], path.xyz_m[k])
        lim = self.arm.limits
        t1 = time.perf_counter()
        try:
            trajectory = time_parameterise(path.t_s, ik.q, lim.lower, lim.upper, self.velocity_limit,
                                           self.acceleration_limit, self.arm.joint_names)
        except LimitViolation as exc:
            raise PathRejected(str(exc), exc.index, path.t_s[exc.index], path.xyz_m[exc.index]) from None
        wall['timing'] = time.perf_counter() - t1
        error = ik.tracking_error()
        error['between_poses_max_m'] = self._between_poses_error(trajectory, targets)
        wall['total'] = time.perf_counter() - t0
        return JointPlan(list(self.arm.joint_names), trajectory, error, float(np.mean(ik.iterations)), wall)

    def _between_poses_error(self, trajectory: TimedJointTrajectory, targets) -> float:
        """Largest distance [m] of the gripper, midway in time between consecutive poses, from the midpoint of the
        straight segment joining the two target positions."""
        if len(trajectory.t_s) < 2:
            return 0.0
        t_mid = 0.5 * (trajectory.t_s[1:] + trajectory.t_s[:-1])
        q_mid, _, _ = trajectory.sample(t_mid)
        p_mid = self.arm.gripper_positions(q_mid)
        p_ref = 0.5 * (targets[1:, :3, 3] + targets[:-1, :3, 3])
        return float(np.max(np.linalg.norm(p_mid - p_ref, axis=1)))

    def lead_in_time(self, q_from, q_to) -> float:
        """Time [s] for a rest-to-rest move q_from -> q_to with every joint within its (scaled) velocity and
        acceleration limits (a cubic with zero end velocities: peak speed 1.5 d / T, peak acceleration 6 d / T^2)."""
        d = np.abs(np.asarray(q_to, dtype=float) - np.asarray(q_from, dtype=float))
        t_v = np.max(1.5 * d / self.velocity_limit)
        t_a = np.max(np.sqrt(6.0 * d / self.acceleration_limit))
        return float(max(t_v, t_a)) * (1.0 + 1e-3)
