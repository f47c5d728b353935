"""Time parameterisation of a joint path under position, velocity and acceleration limits.

The joint positions q_k at the path's stamps t_k are joined by a C2 cubic spline with zero velocity at both ends
(scipy ``CubicSpline``, ``bc_type='clamped'``), checked on a grid of ``samples_per_segment`` points per segment.
If the spline's speed or acceleration exceeds a limit anywhere, the whole trajectory is slowed down uniformly by the
smallest factor s >= 1 that satisfies every limit: t -> s t scales velocities by 1/s and accelerations by 1/s^2, so
s = max(1, max |qd_j| / v_j, sqrt(max |qdd_j| / a_j)). The path's shape (the joint positions at each pose) never
changes, and the stamps are kept exactly when s = 1. A spline that leaves a position limit between poses is an error.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

RETIME_MARGIN = 1e-3     # slow down by this much more than the bare minimum (limits hold on the grid and between)


@dataclass
class TimedJointTrajectory:
    """t_s (K,) from the first pose; q, qd, qdd (K, n) at those times; time_scale: s (1: the path's stamps kept);
    peak_velocity_ratio / peak_acceleration_ratio: the largest |qd_j| / v_j and |qdd_j| / a_j after retiming;
    note: what happened, in words."""
    t_s: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    time_scale: float
    peak_velocity_ratio: float
    peak_acceleration_ratio: float
    note: str
    spline: CubicSpline | None = None

    def sample(self, t_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, qd, qdd at times t_s (from the first pose), held at the ends."""
        t = np.clip(np.asarray(t_s, dtype=float), self.t_s[0], self.t_s[-1])
        return self.spline(t), self.spline(t, 1), self.spline(t, 2)


class LimitViolation(ValueError):
    """The joint path leaves a position limit between poses: ``index`` is the pose before the violation."""

    def __init__(self, message: str, index: int):
        super().__init__(message)
        self.index = index


def time_parameterise(t_s, q, lower, upper, velocity_limit, acceleration_limit, joint_names,
                      samples_per_segment: int = 8) -> TimedJointTrajectory:
    """Timed trajectory through joint positions q (K, n) at stamps t_s (K,), see the module docstring.

    lower / upper [rad]: position limits; velocity_limit [rad/s], acceleration_limit [rad/s^2]: per joint, > 0
    (inf: none). Raises LimitViolation if the spline leaves a position limit.
    """
    t = np.asarray(t_s, dtype=float) - float(t_s[0])
    q = np.asarray(q, dtype=float)
    if len(t) == 1:
        zeros = np.zeros_like(q)
        return TimedJointTrajectory(t, q, zeros, zeros, 1.0, 0.0, 0.0, 'a single pose: held', None)
    spline = CubicSpline(t, q, bc_type='clamped')
    u = np.linspace(0.0, 1.0, samples_per_segment, endpoint=False)
    grid = np.append((t[:-1, None] + np.diff(t)[:, None] * u).ravel(), t[-1])
    q_grid = spline(grid)
    outside = (q_grid < lower - 1e-9) | (q_grid > upper + 1e-9)
    if np.any(outside):
        i, j = (int(v[0]) for v in np.nonzero(outside))
        k = int(np.searchsorted(t, grid[i], side='right') - 1)
        raise LimitViolation(f'between this pose and the next the interpolated joint {joint_names[j]} reaches '
                             f'{q_grid[i, j]:.3f} rad, outside its limits [{lower[j]:.3f}, {upper[j]:.3f}]', k)
    v_ratio = np.abs(spline(grid, 1)) / velocity_limit
    a_ratio = np.abs(spline(grid, 2)) / acceleration_limit
    v_peak, a_peak = float(v_ratio.max()), float(a_ratio.max())
    scale = max(1.0, v_peak, np.sqrt(a_peak))
    if scale > 1.0:
        scale *= 1.0 + RETIME_MARGIN
        jv = int(np.argmax(v_ratio.max(axis=0)))
        ja = int(np.argmax(a_ratio.max(axis=0)))
        limiting = (f'velocity of {joint_names[jv]} ({v_peak:.2f} x its limit)' if v_peak >= a_peak ** 0.5 else
                    f'acceleration of {joint_names[ja]} ({a_peak:.2f} x its limit)')
        note = (f'slowed down: the path\'s stamps would exceed the {limiting}; every stamp stretched by '
                f'{scale:.3f} ({t[-1]:.2f} s -> {t[-1] * scale:.2f} s)')
        t = t * scale
        spline = CubicSpline(t, q, bc_type='clamped')
    else:
        note = 'the path\'s stamps are kept (every joint within its velocity and acceleration limits)'
    return TimedJointTrajectory(t, q, spline(t, 1), spline(t, 2), float(scale), v_peak / scale,
                                a_peak / scale ** 2, note, spline)
