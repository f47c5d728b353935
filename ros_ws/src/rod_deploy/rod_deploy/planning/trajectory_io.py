"""Gripper trajectory CSV (CONTRACTS.md section 4): ``t,x,y,z,qx,qy,qz,qw``.

Seconds, metres, unit quaternion scalar-last, in the table frame (z up, table surface z = 0); (x, y, z) is the held
(last) node of the rod, +z_gripper the direction in which the rod leaves the gripper; ``t`` strictly increasing.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

HEADER = 't,x,y,z,qx,qy,qz,qw'


class TrajectoryFileError(ValueError):
    """A trajectory file that does not follow the contract."""


def write_trajectory_csv(path, t, position, quaternion):
    t = np.asarray(t, float)
    position = np.asarray(position, float)
    quaternion = np.asarray(quaternion, float)
    _validate(t, position, quaternion, str(path))
    data = np.column_stack([t, position, quaternion])
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, data, delimiter=',', header=HEADER, comments='', fmt='%.9g')


def read_trajectory_csv(path):
    """-> (t (n,), position (n, 3), quaternion (n, 4) scalar-last), validated."""
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as e:
        raise TrajectoryFileError(f'cannot read trajectory {path}: {e.strerror}') from None
    if not lines or lines[0].replace(' ', '') != HEADER:
        raise TrajectoryFileError(f'trajectory {path}: the first line must be the header "{HEADER}"')
    try:
        data = np.loadtxt(path, delimiter=',', skiprows=1, ndmin=2)
    except ValueError as e:
        raise TrajectoryFileError(f'trajectory {path}: not 8 numbers per row ({e})') from None
    if data.shape[1] != 8 or len(data) < 2:
        raise TrajectoryFileError(f'trajectory {path}: need at least 2 rows of 8 numbers, got shape {data.shape}')
    t, p, q = data[:, 0], data[:, 1:4], data[:, 4:8]
    _validate(t, p, q, str(path))
    return t, p, q / np.linalg.norm(q, axis=1, keepdims=True)


def _validate(t, p, q, name):
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
        i = int(np.flatnonzero(~(np.isfinite(t) & np.all(np.isfinite(p), 1) & np.all(np.isfinite(q), 1)))[0])
        raise TrajectoryFileError(f'trajectory {name}: row {i + 1} is not finite')
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise TrajectoryFileError(f'trajectory {name}: t is not strictly increasing at row {bad[0] + 2} '
                                  f'(t = {t[bad[0] + 1]:.6g} after {t[bad[0]]:.6g})')
    norms = np.linalg.norm(q, axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > 1e-3)
    if bad.size:
        raise TrajectoryFileError(f'trajectory {name}: quaternion of row {bad[0] + 1} is not a unit quaternion '
                                  f'(norm {norms[bad[0]]:.6g})')
