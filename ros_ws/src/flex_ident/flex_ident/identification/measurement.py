"""Recorded joint log (contract bag) -> :class:`~.problem.MeasuredData` on a uniform time grid.

The bag is read by the robot_bridge contract reader (header stamps as the time base, joints by name, window), which
raises BagError (a ValueError) for missing joints, missing efforts, NaN, a bag shorter than the window. Here: the
sample period is the median stamp spacing; jittered stamps are resampled linearly onto a uniform grid.
"""
from __future__ import annotations

import numpy as np

from .problem import MeasuredData

MIN_SAMPLES = 20
REST_TOLERANCE_RAD = 2e-3
REST_CHECK_S = 0.3


class MeasurementError(ValueError):
    """A recording that cannot be used for identification."""


def uniform_grid(t_s, position, effort, name: str = 'recording') -> MeasuredData:
    t = np.asarray(t_s, float)
    if len(t) < MIN_SAMPLES:
        raise MeasurementError(f'{name} has {len(t)} samples in the window; identification needs at least '
                               f'{MIN_SAMPLES}')
    steps = np.diff(t)
    dt = float(np.median(steps))
    if not (1e-4 <= dt <= 0.1):
        raise MeasurementError(f'{name}: sample period {dt:.6f} s is outside 0.1 ms ... 100 ms')
    t0 = t - t[0]
    if np.max(np.abs(steps - dt)) > 0.05 * dt:
        k = int(np.floor(t0[-1] / dt + 1e-9)) + 1
        grid = np.arange(k) * dt
        position = np.stack([np.interp(grid, t0, position[:, j]) for j in range(position.shape[1])], axis=1)
        effort = np.stack([np.interp(grid, t0, effort[:, j]) for j in range(effort.shape[1])], axis=1)
        t0 = grid
    else:
        t0 = np.arange(len(t)) * dt
    return MeasuredData(t_s=t0, names=[], theta=np.ascontiguousarray(position, float),
                        tau=np.ascontiguousarray(effort, float))


def load_measurements(bag_path, joints, window=None) -> tuple[MeasuredData, dict]:
    """Read the bag's /joint_states for ``joints`` (model input order) within ``window``; returns the data and
    notes for the report (sample period, resampling, whether the arm starts at rest)."""
    from robot_bridge.bagio.contract import read_joint_recording

    rec = read_joint_recording(str(bag_path), joints=list(joints), window=window, require_effort=True)
    data = uniform_grid(rec.t_s, rec.position, rec.effort, f'bag {bag_path}')
    data.names = list(rec.names)
    first = data.theta[:max(3, int(round(REST_CHECK_S / data.dt)))]
    motion = float(np.max(np.abs(first - np.median(first, axis=0))))
    # encoder noise (from sample-to-sample differences, which a slow motion hardly changes) must not read as motion
    noise = float(np.median(np.std(np.diff(first, axis=0), axis=0)) / np.sqrt(2.0))
    tolerance = max(REST_TOLERANCE_RAD, 6.0 * noise)
    notes = {'samples': int(len(data.t_s)), 'sample_period_s': data.dt,
             'window_s': [float(rec.t_s[0]), float(rec.t_s[-1])],
             'starts_at_rest': bool(motion <= tolerance),
             'initial_motion_rad': motion, 'rest_tolerance_rad': tolerance}
    return data, notes
