"""Small rigid-body helpers: rotations, homogeneous transforms, inertia tensors (SI units throughout).

Conventions: a pose is a 4x4 homogeneous matrix ``g = [[R, p], [0, 1]]`` mapping child-frame coordinates to
parent-frame coordinates; ``rpy`` follows URDF, R = Rz(yaw) Ry(pitch) Rx(roll).
"""
from __future__ import annotations

import numpy as np

from robot_bridge.geometry import rot_x, rot_y, rot_z, rpy_matrix  # noqa: F401  (URDF conventions, shared)


def skew(w) -> np.ndarray:
    """[w]x, the 3x3 matrix with [w]x v = w x v."""
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def rot_axis(axis, angle_rad: float) -> np.ndarray:
    """Rotation by ``angle_rad`` about the unit vector ``axis`` (Rodrigues)."""
    k = skew(np.asarray(axis, dtype=float))
    return np.eye(3) + np.sin(angle_rad) * k + (1.0 - np.cos(angle_rad)) * (k @ k)


def transform(R=None, p=None) -> np.ndarray:
    """Homogeneous 4x4 transform from a rotation matrix and a translation [m]."""
    g = np.eye(4)
    if R is not None:
        g[:3, :3] = R
    if p is not None:
        g[:3, 3] = p
    return g


def pose_xyz_rpy(xyz, rpy) -> np.ndarray:
    """Homogeneous transform T(xyz) R(rpy), URDF's <origin>."""
    return transform(rpy_matrix(rpy), np.asarray(xyz, dtype=float))


def trans(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    return transform(p=[x, y, z])


def roty(a: float) -> np.ndarray:
    return transform(R=rot_y(a))


def inertia_matrix(ixx, ixy, ixz, iyy, iyz, izz) -> np.ndarray:
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=float)


def solid_cylinder_inertia(mass_kg: float, radius_m: float, length_m: float, axis: int = 0) -> np.ndarray:
    """Inertia tensor [kg m^2] of a solid cylinder about its centre, its symmetry axis along ``axis``."""
    axial = 0.5 * mass_kg * radius_m ** 2
    transverse = mass_kg * (3.0 * radius_m ** 2 + length_m ** 2) / 12.0
    inertia = np.full(3, transverse)
    inertia[axis] = axial
    return np.diag(inertia)


def combine_inertias(parts):
    """Combine rigidly attached bodies into one.

    parts: iterable of (mass_kg, com (3,), inertia about com (3,3)), all in one frame.
    Returns (mass, com, inertia about the combined com) in that frame; a massless result has com 0.
    """
    parts = list(parts)
    mass = float(sum(m for m, _, _ in parts))
    if mass <= 0.0:
        return 0.0, np.zeros(3), sum((np.asarray(i, dtype=float) for _, _, i in parts), np.zeros((3, 3)))
    com = sum(m * np.asarray(c, dtype=float) for m, c, _ in parts) / mass
    inertia = np.zeros((3, 3))
    for m, c, i_c in parts:
        d = np.asarray(c, dtype=float) - com
        inertia += np.asarray(i_c, dtype=float) + m * (d @ d * np.eye(3) - np.outer(d, d))
    return mass, com, inertia

