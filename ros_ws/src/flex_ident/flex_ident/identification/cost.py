"""Tracking costs (paper Sec. IV-E): J = sum_k l_k(x_k) + m(x_K) on the sample grid.

* ``end_effector`` (the paper's): l_k = |y(q_k) - y_meas,k|^2 / T with y the end-effector (grasp frame) position
  from forward kinematics and y_meas,k the same point at the measured arm angles; the terminal cost m has the same
  form at k = T-1.
* ``joint_angles``: l_k = |S q_k - theta_meas,k|^2 / T (S picks the measured arm angles).

Both are written as a stacked residual r (T*d,) with J = |r|^2, so Gauss-Newton / Levenberg-Marquardt can use the
residual Jacobian dr/dc = blockdiag(C_k) dq_k/dc, and the adjoint uses dl_k/dx_k = 2 C_k^T r_k.
Errors are reported as RMS: ee_rms_m = sqrt(mean_k |y_k - y_meas,k|^2), joint_rms_rad = sqrt(mean over k, joints).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mechanics.tree_kinematics import point_positions

COSTS = ('end_effector', 'joint_angles')


def end_effector_positions(model, Q, frame: str = 'ee'):
    """Positions (T, 3) [m, base frame] and Jacobians (T, 3, n) of a named frame's origin along Q (T, n)."""
    coord, offset = model.frames[frame]
    Q = np.ascontiguousarray(np.atleast_2d(Q), dtype=float)
    Y = np.empty((Q.shape[0], 3))
    C = np.empty((Q.shape[0], 3, model.n))
    point_positions(model.kernel(), Q, coord, np.ascontiguousarray(offset[:3, 3]), Y, C)
    return Y, C


@dataclass
class TrackingCost:
    model: object
    kind: str                   # 'end_effector' | 'joint_angles'
    theta_meas: np.ndarray      # (T, na) measured arm angles on the sample grid
    y_meas: np.ndarray          # (T, 3) measured end-effector positions

    @classmethod
    def create(cls, model, theta_meas, kind: str = 'end_effector'):
        if kind not in COSTS:
            raise ValueError(f'unknown cost "{kind}": use one of {COSTS}')
        Q = np.zeros((len(theta_meas), model.n))
        Q[:, model.measured_coords] = theta_meas
        y_meas, _ = end_effector_positions(model, Q)
        return cls(model=model, kind=kind, theta_meas=np.asarray(theta_meas, float), y_meas=y_meas)

    @property
    def T(self) -> int:
        return len(self.theta_meas)

    def residual_and_output_jacobian(self, Q):
        """r (T, d) per-sample residuals scaled by 1/sqrt(T) and C (T, d, n) = dr_k/dq_k."""
        scale = 1.0 / np.sqrt(self.T)
        if self.kind == 'end_effector':
            Y, C = end_effector_positions(self.model, Q)
            return scale * (Y - self.y_meas), scale * C
        idx = self.model.measured_coords
        r = scale * (Q[:, idx] - self.theta_meas)
        C = np.zeros((self.T, len(idx), self.model.n))
        C[:, np.arange(len(idx)), idx] = scale
        return r, C

    def value(self, Q) -> float:
        r, _ = self.residual_and_output_jacobian(Q)
        return float(np.sum(r * r))

    def errors(self, Q, part: slice = slice(None)) -> dict:
        """RMS errors of a simulated configuration sequence against the measurement (on the samples ``part``)."""
        Q = Q[part]
        Y, _ = end_effector_positions(self.model, Q)
        ee = np.sqrt(np.mean(np.sum((Y - self.y_meas[part]) ** 2, axis=1)))
        joint = np.sqrt(np.mean((Q[:, self.model.measured_coords] - self.theta_meas[part]) ** 2))
        return {'ee_rms_m': float(ee), 'joint_rms_rad': float(joint)}
