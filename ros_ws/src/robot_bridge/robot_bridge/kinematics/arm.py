"""A serial arm from a URDF as a Pinocchio model, built once; its gripper frame; forward kinematics and Jacobians.

The chain base_link -> tip_link is read with ``robot_bridge.sim.urdf_arm`` (the same parser the MuJoCo simulator
uses) and built joint by joint into a ``pinocchio.Model``: each joint listed in ``joints`` becomes a 1-DoF revolute
(or prismatic) joint about its URDF axis (``continuous`` = revolute without position limits), every other joint of the
chain (fixed, or movable but not listed, held at 0) is folded into the next placement. The gripper frame G is the
tip_link frame composed with the grasp offset (4x4, G in tip_link). Poses are in the base_link frame, metres.
"""
from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from robot_bridge.sim.urdf_arm import UrdfRobot, parse_urdf

BAXTER_RIGHT_JOINTS = ('right_s0', 'right_s1', 'right_e0', 'right_e1', 'right_w0', 'right_w1', 'right_w2')


def default_urdf_path() -> Path:
    """The project's Baxter right arm (package data of flex_ident), found without importing flex_ident."""
    spec = importlib.util.find_spec('flex_ident')
    if spec is None or not spec.submodule_search_locations:
        raise ValueError('the default arm URDF ships with flex_ident, which is not installed; pass a urdf path')
    return Path(list(spec.submodule_search_locations)[0]) / 'data' / 'baxter_right_arm.urdf'


@dataclass
class JointLimits:
    """Per joint (model order): position bounds [rad or m] (+-inf when unbounded), speed limit [rad/s or m/s]
    (inf when the URDF gives none)."""
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray


class ArmKinematics:
    """Pinocchio model of the chain base_link -> tip_link with a gripper frame; one ``Data`` reused by every call.

    Not thread-safe (the Data is shared): one instance per thread.
    """

    def __init__(self, urdf: str | Path | UrdfRobot, base_link: str, tip_link: str, joints: list[str] | tuple,
                 grasp: np.ndarray | None = None):
        robot = urdf if isinstance(urdf, UrdfRobot) else parse_urdf(urdf)
        chain = robot.chain(base_link, tip_link)
        joints = list(joints)
        movable = [j.name for j in chain if j.movable]
        for name in joints:
            if name not in robot.joints:
                raise ValueError(f"URDF '{robot.name}' has no joint '{name}'")
            if name not in movable:
                raise ValueError(f"joint '{name}' is not a movable joint between '{base_link}' and '{tip_link}'")
        order = [j.name for j in chain if j.name in joints]
        if order != joints:
            raise ValueError(f'joints must be listed in chain order from {base_link} to {tip_link}: {order}')
        self.robot, self.base_link, self.tip_link, self.joint_names = robot, base_link, tip_link, joints
        self.grasp = np.eye(4) if grasp is None else np.asarray(grasp, dtype=float)

        model = pin.Model()
        model.name = robot.name
        parent, placement = 0, np.eye(4)
        lower, upper, velocity = [], [], []
        for joint in chain:
            placement = placement @ joint.origin
            if joint.name not in joints:
                continue            # fixed, or a movable joint held at 0: folded into the next placement
            axis = np.asarray(joint.axis, dtype=float)
            jmodel = (pin.JointModelPrismaticUnaligned(axis) if joint.type == 'prismatic'
                      else pin.JointModelRevoluteUnaligned(axis))
            lo = -np.inf if joint.lower is None else joint.lower
            hi = np.inf if joint.upper is None else joint.upper
            vel = np.inf if not joint.velocity else joint.velocity
            parent = model.addJoint(parent, jmodel, pin.SE3(placement), joint.name,
                                    np.array([joint.effort or np.inf]), np.array([vel]),
                                    np.array([lo]), np.array([hi]))
            lower.append(lo)
            upper.append(hi)
            velocity.append(vel)
            placement = np.eye(4)
        self.frame_id = model.addFrame(pin.Frame('gripper', parent, pin.SE3(placement @ self.grasp),
                                                 pin.FrameType.OP_FRAME))
        self.model = model
        self.data = model.createData()
        self.limits = JointLimits(np.array(lower), np.array(upper), np.array(velocity))
        self.nq = model.nq

    def gripper_pose(self, q) -> np.ndarray:
        """G (4x4, base_link frame) at joint positions q."""
        return self.gripper_se3(q).homogeneous

    def gripper_se3(self, q) -> pin.SE3:
        """G at q (a copy; the kinematics in ``data`` are left at q)."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return pin.SE3(self.data.oMf[self.frame_id])

    def gripper_jacobian(self, q) -> np.ndarray:
        """6 x nq Jacobian of G in G's own (LOCAL) frame: (linear, angular) velocity of G per joint velocity.

        Expects the kinematics at q to be current (call ``gripper_se3(q)`` first)."""
        return pin.computeFrameJacobian(self.model, self.data, np.asarray(q, dtype=float), self.frame_id,
                                        pin.LOCAL)

    def gripper_positions(self, qs) -> np.ndarray:
        """Origins of G (K x 3, base_link frame) for joint positions qs (K x nq)."""
        return np.array([self.gripper_se3(q).translation for q in np.atleast_2d(qs)])

    def chain_points(self, q) -> np.ndarray:
        """(nq + 2, 3) points of the arm at q in base_link: the base origin, every joint origin, the gripper frame's
        origin (a stick figure of the pose, e.g. for markers)."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        joints = [self.data.oMi[j].translation.copy() for j in range(1, self.model.njoints)]
        return np.vstack([np.zeros(3)] + joints + [self.data.oMf[self.frame_id].translation.copy()])
