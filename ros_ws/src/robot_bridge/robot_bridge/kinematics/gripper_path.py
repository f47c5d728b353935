"""The gripper trajectory of CONTRACTS.md section 4: stamped poses of the gripper frame in the table frame.

CSV header ``t,x,y,z,qx,qy,qz,qw`` (s, m, unit quaternion scalar-last); table frame z up, the table surface at z = 0;
+z_gripper is the direction in which the rod leaves the gripper. ``validate`` names the first bad pose (index, time,
xyz) of an empty path, a non-finite value, a quaternion that is not unit length or a time that does not increase.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

CSV_HEADER = ('t', 'x', 'y', 'z', 'qx', 'qy', 'qz', 'qw')
QUATERNION_NORM_TOLERANCE = 1e-3


class PathRejected(ValueError):
    """A path the bridge refuses before anything moves; names the first bad pose (index, t [s], xyz [m, table])."""

    def __init__(self, reason: str, index: int | None = None, t_s: float | None = None, xyz=None):
        self.reason, self.index, self.t_s = reason, index, t_s
        self.xyz = None if xyz is None else [float(v) for v in xyz]
        if index is None:
            super().__init__(reason)
        else:
            where = f'pose {index}'
            if t_s is not None and np.isfinite(t_s):
                where += f' (t = {t_s:.3f} s'
                where += f', xyz = [{", ".join(f"{v:.4f}" for v in self.xyz)}] m in the table frame)' \
                    if self.xyz is not None else ')'
            super().__init__(f'{where}: {reason}')


@dataclass
class GripperPath:
    """t_s (K,), xyz_m (K, 3), quat_xyzw (K, 4): gripper poses in the table frame (CONTRACTS.md section 4)."""
    t_s: np.ndarray
    xyz_m: np.ndarray
    quat_xyzw: np.ndarray

    def __len__(self) -> int:
        return len(self.t_s)

    def validate(self) -> 'GripperPath':
        """Raise PathRejected for the first bad pose; return self."""
        t, xyz, quat = (np.asarray(a, dtype=float) for a in (self.t_s, self.xyz_m, self.quat_xyzw))
        if len(t) == 0:
            raise PathRejected('the path is empty')
        if xyz.shape != (len(t), 3) or quat.shape != (len(t), 4):
            raise PathRejected(f'expected {len(t)} xyz triples and quaternions, got shapes {xyz.shape}, {quat.shape}')
        for k in range(len(t)):
            if not (np.isfinite(t[k]) and np.all(np.isfinite(xyz[k])) and np.all(np.isfinite(quat[k]))):
                raise PathRejected('NaN or infinite value in the pose or its time', k, t[k], xyz[k])
            norm = np.linalg.norm(quat[k])
            if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
                raise PathRejected(f'quaternion (qx, qy, qz, qw) = {np.round(quat[k], 4).tolist()} has norm '
                                   f'{norm:.4g}, not 1', k, t[k], xyz[k])
            if k and not t[k] > t[k - 1]:
                raise PathRejected(f'time does not increase (previous pose at t = {t[k - 1]:.6g} s)', k, t[k], xyz[k])
        return self

    def transforms(self) -> np.ndarray:
        """(K, 4, 4) poses of the gripper frame in the table frame (quaternions normalised)."""
        out = np.tile(np.eye(4), (len(self), 1, 1))
        out[:, :3, :3] = Rotation.from_quat(np.asarray(self.quat_xyzw, dtype=float)).as_matrix()
        out[:, :3, 3] = self.xyz_m
        return out

    @classmethod
    def from_transforms(cls, t_s, poses) -> 'GripperPath':
        poses = np.asarray(poses, dtype=float)
        return cls(np.asarray(t_s, dtype=float), poses[:, :3, 3].copy(),
                   Rotation.from_matrix(poses[:, :3, :3]).as_quat())


def read_gripper_csv(path: str | Path) -> GripperPath:
    """Read the contract CSV (header ``t,x,y,z,qx,qy,qz,qw``, columns in any order). Raises ValueError on a
    missing file, a missing column or a cell that is not a number (NaN cells are kept for ``validate``)."""
    path = Path(path)
    try:
        with path.open(newline='') as f:
            rows = list(csv.reader(f))
    except OSError as exc:
        raise ValueError(f'cannot read gripper trajectory {path}: {exc.strerror}') from None
    rows = [r for r in rows if r and any(c.strip() for c in r)]
    if not rows:
        raise ValueError(f'{path} is empty (expected the header {",".join(CSV_HEADER)})')
    header = [c.strip() for c in rows[0]]
    missing = [c for c in CSV_HEADER if c not in header]
    if missing:
        raise ValueError(f'{path}: header {header} lacks column(s) {missing} (expected {",".join(CSV_HEADER)})')
    cols = [header.index(c) for c in CSV_HEADER]
    data = np.empty((len(rows) - 1, len(CSV_HEADER)))
    for i, row in enumerate(rows[1:]):
        try:
            data[i] = [float(row[c]) for c in cols]
        except (ValueError, IndexError):
            raise ValueError(f'{path}: line {i + 2} is not {len(CSV_HEADER)} numbers: {",".join(row)}') from None
    return GripperPath(data[:, 0], data[:, 1:4], data[:, 4:8])


def write_gripper_csv(path: str | Path, gripper_path: GripperPath):
    data = np.column_stack([gripper_path.t_s, gripper_path.xyz_m, gripper_path.quat_xyzw])
    np.savetxt(path, data, delimiter=',', header=','.join(CSV_HEADER), comments='', fmt='%.9g')
