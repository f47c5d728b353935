"""Homogeneous transforms in URDF's conventions (R = Rz(yaw) Ry(pitch) Rx(roll)) and MuJoCo quaternions (w x y z)."""
from __future__ import annotations

import numpy as np

from robot_bridge.geometry import rot_x, rot_y, rot_z, rpy_matrix  # noqa: F401  (re-exported)


def matrix_rpy(rot: np.ndarray) -> np.ndarray:
    """Rotation matrix -> URDF rpy [rad] (inverse of rpy_matrix away from pitch = +-pi/2)."""
    pitch = np.arcsin(-np.clip(rot[2, 0], -1.0, 1.0))
    roll = np.arctan2(rot[2, 1], rot[2, 2])
    yaw = np.arctan2(rot[1, 0], rot[0, 0])
    return np.array([roll, pitch, yaw])


def transform(rot: np.ndarray | None = None, xyz=(0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4 homogeneous transform from a rotation matrix and a translation [m]."""
    out = np.eye(4)
    if rot is not None:
        out[:3, :3] = rot
    out[:3, 3] = np.asarray(xyz, dtype=float)
    return out


def pose_transform(xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)) -> np.ndarray:
    """URDF-style origin (xyz [m], rpy [rad]) -> 4x4 transform."""
    return transform(rpy_matrix(rpy), xyz)


def matrix_quat(rot: np.ndarray) -> np.ndarray:
    """Rotation matrix -> unit quaternion (w, x, y, z), w >= 0 (Shepperd's method)."""
    m = np.asarray(rot, dtype=float)
    tr = np.trace(m)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.asarray(q)
    q /= np.linalg.norm(q)
    return -q if q[0] < 0 else q


def rotation_angle(rot: np.ndarray) -> float:
    """Angle [rad] of a rotation matrix (0 for the identity)."""
    return float(np.arccos(np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0)))


def rotation_vector(rot: np.ndarray) -> np.ndarray:
    """Rotation matrix -> axis * angle [rad] (log map), robust near 0."""
    angle = rotation_angle(rot)
    w = np.array([rot[2, 1] - rot[1, 2], rot[0, 2] - rot[2, 0], rot[1, 0] - rot[0, 1]])
    if angle < 1e-6:
        return 0.5 * w
    if np.pi - angle < 1e-6:   # near pi: axis from the symmetric part
        axis = np.sqrt(np.clip((np.diag(rot) + 1.0) / 2.0, 0.0, None))
        k = int(np.argmax(axis))
        axis = (rot[:, k] + np.eye(3)[:, k]) / (2.0 * axis[k])
        return angle * axis / np.linalg.norm(axis)
    return angle / (2.0 * np.sin(angle)) * w
