"""Synthetic gripper paths shaped like a rod deployment, for benchmarks and tests (table frame, CONTRACTS.md sec. 4).

The gripper circles above a pattern on the table while it rises and falls between two heights and tilts: +z_gripper
(the rod's direction out of the gripper) starts straight down (quaternion (1, 0, 0, 0)) and leans by up to
``max_tilt_rad`` away from the direction of travel, as a rod laid behind a moving gripper pulls it.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .gripper_path import GripperPath


def deployment_like_path(n_poses: int = 200, duration_s: float = 20.0, centre_xy_m=(0.0, 0.0),
                         radius_m: float = 0.15, height_m=(0.3, 0.9), max_tilt_rad: float = np.radians(60.0),
                         turns: float = 1.0) -> GripperPath:
    """n_poses poses at even stamps over duration_s: a circle of radius_m about centre_xy_m (table frame), the height
    going from height_m[0] up to height_m[1] and back, the tilt growing from 0 to max_tilt_rad and back."""
    t = np.linspace(0.0, duration_s, n_poses)
    s = t / duration_s
    bump = np.sin(np.pi * s) ** 2                       # 0 at both ends, 1 midway
    phase = 2.0 * np.pi * turns * s
    xyz = np.column_stack([centre_xy_m[0] + radius_m * np.cos(phase), centre_xy_m[1] + radius_m * np.sin(phase),
                           height_m[0] + (height_m[1] - height_m[0]) * bump])
    heading = phase + np.pi / 2.0                        # direction of travel on the circle
    hanging = Rotation.from_quat([1.0, 0.0, 0.0, 0.0])   # +z_gripper = -z_table
    # tilt about the horizontal axis perpendicular to the travel direction, so that +z_gripper leans backwards
    axes = np.column_stack([-np.sin(heading), np.cos(heading), np.zeros_like(s)])
    tilt = Rotation.from_rotvec((max_tilt_rad * bump)[:, None] * axes)
    return GripperPath(t, xyz, (tilt * hanging).as_quat())
