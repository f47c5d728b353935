"""What the arm actually did: the gripper path of measured joint states over a commanded trajectory.

The arm executes a joint trajectory whose points k are due at ``time_from_start_k`` after the (unknown) instant
``s0`` at which the controller took the command, on the clock of the joint-state stamps. ``s0`` is fitted within
bounds (from a lower bound such as the stamp of the last joint state received when the command went out, which a
loaded machine may deliver late, to the latest start the measurements still cover): the offset that minimises the
squared joint-space distance between the measured joints, interpolated at s0 + time_from_start_k, and the
commanded points (a 1-D search, 5 ms grid then 0.25 ms grid). The executed gripper path is the forward
kinematics of the measured joints at those instants (``ArmCommandPlanner.executed_path``), one pose per commanded
point, in the table frame; its deviation from the planned gripper path is the tracking error of the whole chain
(IK, timing, controller).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .gripper_path import GripperPath
from .planner import ArmCommandPlanner


class ExecutionError(ValueError):
    """Measured joint states that cannot give the executed path (too few, missing joints, not covering the
    command)."""


@dataclass
class ExecutedPath:
    path: GripperPath                 # one pose per commanded point, t from the first point [s], table frame
    start_stamp_s: float              # fitted s0 on the joint-state clock [s]
    start_correction_s: float         # s0 - the earliest possible start [s]
    joint_rms_rad: float              # RMS of measured - commanded joints at the fitted s0
    samples_used: int


def joint_matrix(names_per_sample, positions_per_sample, joint_names) -> np.ndarray:
    """(K, n) joint positions in ``joint_names`` order from JointState-like (name list, position list) pairs; a
    sample without every joint raises ExecutionError."""
    out = np.empty((len(positions_per_sample), len(joint_names)))
    for k, (names, pos) in enumerate(zip(names_per_sample, positions_per_sample)):
        index = {n: i for i, n in enumerate(names)}
        try:
            out[k] = [pos[index[j]] for j in joint_names]
        except (KeyError, IndexError):
            missing = [j for j in joint_names if j not in index]
            raise ExecutionError(f'joint state {k} lacks joint(s) {missing}') from None
    return out


def fit_start(stamps_s, q_meas, times_from_start_s, q_cmd, earliest_s: float, latest_s: float) -> tuple:
    """(s0, joint RMS at s0): the command's start on the measurement clock within [earliest_s, latest_s]."""
    stamps_s = np.asarray(stamps_s, float)

    def cost(s0):
        t = s0 + times_from_start_s
        q = np.column_stack([np.interp(t, stamps_s, q_meas[:, j]) for j in range(q_meas.shape[1])])
        return float(np.mean(np.sum((q - q_cmd) ** 2, axis=1)))

    grid = np.arange(earliest_s, max(latest_s, earliest_s) + 2.5e-3, 5e-3)
    best = float(grid[int(np.argmin([cost(s) for s in grid]))])
    grid = best + np.arange(-5e-3, 5e-3 + 1e-4, 2.5e-4)
    best = float(grid[int(np.argmin([cost(s) for s in grid]))])
    return best, float(np.sqrt(cost(best)))


def executed_gripper_path(planner: ArmCommandPlanner, stamps_s, q_meas, times_from_start_s, q_cmd,
                          earliest_start_s: float) -> ExecutedPath:
    """The gripper path the arm executed for a command (points q_cmd at times_from_start_s), from joint states
    (stamps_s, q_meas in the planner's joint order) that cover the command, which started at earliest_start_s or
    later."""
    stamps_s, q_meas = np.asarray(stamps_s, float), np.asarray(q_meas, float)
    tfs, q_cmd = np.asarray(times_from_start_s, float), np.asarray(q_cmd, float)
    if len(stamps_s) < 2 or len(tfs) < 1:
        raise ExecutionError(f'{len(stamps_s)} joint states for a command of {len(tfs)} points')
    if np.any(np.diff(stamps_s) <= 0):
        raise ExecutionError('joint-state stamps do not increase')
    latest = stamps_s[-1] - tfs[-1]
    if latest < earliest_start_s:
        raise ExecutionError(f'the joint states end {earliest_start_s - latest:.3f} s before the command does')
    s0, rms = fit_start(stamps_s, q_meas, tfs, q_cmd, earliest_start_s, latest)
    t = s0 + tfs
    q = np.column_stack([np.interp(t, stamps_s, q_meas[:, j]) for j in range(q_meas.shape[1])])
    used = int(np.count_nonzero((stamps_s >= t[0]) & (stamps_s <= t[-1])))
    return ExecutedPath(planner.executed_path(tfs - tfs[0], q), s0, s0 - earliest_start_s, rms, used)


def path_deviation_m(a: GripperPath, b: GripperPath) -> dict:
    """Position distance between two paths pose by pose (same length): max and RMS [m]."""
    d = np.linalg.norm(np.asarray(a.xyz_m) - np.asarray(b.xyz_m), axis=1)
    return {'max_m': float(d.max()), 'rms_m': float(np.sqrt(np.mean(d ** 2)))}
