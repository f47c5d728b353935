"""The recorded-interaction contract (CONTRACTS.md section 1): joint logs as rosbag2 <-> arrays.

``/joint_states`` (sensor_msgs/msg/JointState): ``header.stamp`` is the time base (the bag's receive time
may lag it); ``name`` may list joints in any order and joints outside the model; positions in rad,
velocities in rad/s (may be empty), efforts in N m (actuator torque). Other topics are ignored.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .raw import TYPESTORE, BagError, RawBagWriter, deserialize, iter_raw_messages, serialize

JOINT_STATES = '/joint_states'
JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'


@dataclass
class JointRecording:
    """A joint log on a common time base.

    t_s: (K,) seconds from the first /joint_states header stamp. position/velocity/effort: (K, n) in the
    order of ``names`` (rad, rad/s, N m); velocity or effort is None when the log has none.
    stamp0_ns: the absolute header stamp of the first sample.
    """
    t_s: np.ndarray
    names: list[str]
    position: np.ndarray
    velocity: np.ndarray | None = None
    effort: np.ndarray | None = None
    stamp0_ns: int = 0

    def __post_init__(self):
        k, n = len(self.t_s), len(self.names)
        for field in ('position', 'velocity', 'effort'):
            arr = getattr(self, field)
            if arr is not None and np.shape(arr) != (k, n):
                raise ValueError(f'{field} has shape {np.shape(arr)}, expected ({k}, {n}) '
                                 f'for {k} samples of {n} joints')


def _stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def read_joint_recording(bag_path: str | Path, joints: list[str] | None = None,
                         window: tuple[float, float] | None = None,
                         require_effort: bool = False) -> JointRecording:
    """Read ``/joint_states`` of a contract bag into arrays.

    joints: the joints to extract, in this order (default: the names of the first message).
    window: (start, end) seconds from the first header stamp; the bag must cover it.
    Raises BagError naming the problem: no /joint_states, a missing joint, missing efforts,
    NaN in a selected joint, a bag shorter than the window.
    """
    msgs = []
    for raw in iter_raw_messages(bag_path, topics=[JOINT_STATES]):
        if raw.msgtype != JOINT_STATE_TYPE:
            raise BagError(f'{JOINT_STATES} in {bag_path} has type {raw.msgtype}, expected {JOINT_STATE_TYPE}')
        msgs.append(deserialize(raw.data, raw.msgtype))
    if not msgs:
        raise BagError(f'bag {bag_path} has no {JOINT_STATES} messages')
    msgs.sort(key=lambda m: _stamp_ns(m.header))
    names = list(joints) if joints is not None else list(msgs[0].name)
    k, n = len(msgs), len(names)
    stamps = np.empty(k, dtype=np.int64)
    out = {f: np.full((k, n), np.nan) for f in ('position', 'velocity', 'effort')}
    present = {f: True for f in out}
    for i, m in enumerate(msgs):
        stamps[i] = _stamp_ns(m.header)
        index = {name: j for j, name in enumerate(m.name)}
        missing = [name for name in names if name not in index]
        if missing:
            raise BagError(f'joint(s) {missing} missing from {JOINT_STATES} message {i} '
                           f'(it has {list(m.name)})')
        cols = [index[name] for name in names]
        for field in out:
            values = np.asarray(getattr(m, field), dtype=float)
            if len(values) == 0:
                present[field] = False
                continue
            if len(values) != len(m.name):
                raise BagError(f'{JOINT_STATES} message {i}: {field} has {len(values)} values '
                               f'for {len(m.name)} names')
            out[field][i] = values[cols]
    if not present['position']:
        raise BagError(f'{JOINT_STATES} in {bag_path} carries no positions')
    if require_effort and not present['effort']:
        raise BagError(f'{JOINT_STATES} in {bag_path} carries no efforts (joint torques), '
                       'which identification needs')
    t = (stamps - stamps[0]) * 1e-9
    if np.any(np.diff(t) <= 0):
        dup = int(np.sum(np.diff(t) <= 0))
        raise BagError(f'{JOINT_STATES} has {dup} repeated header stamps')
    if window is not None:
        t0, t1 = float(window[0]), float(window[1])
        if not (0 <= t0 < t1):
            raise BagError(f'window {window} is not an increasing pair of non-negative seconds')
        # A window [0, 20] on 2000 samples at 100 Hz (last stamp 19.99 s) is the whole recording:
        # allow one sample period of slack at the end, no more.
        period = float(np.median(np.diff(t))) if k > 1 else 0.0
        if t1 > t[-1] + 1.01 * period + 1e-9:
            raise BagError(f'bag {bag_path} covers {t[-1]:.3f} s of {JOINT_STATES}, '
                           f'shorter than the window end {t1} s')
        sel = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    else:
        sel = np.ones(k, dtype=bool)
    rec = {f: (out[f][sel] if present[f] else None) for f in out}
    for field, arr in rec.items():
        if arr is not None and not np.all(np.isfinite(arr)):
            rows, cols = np.nonzero(~np.isfinite(arr))
            raise BagError(f'{field} of joint {names[cols[0]]} is not finite at t = '
                           f'{t[sel][rows[0]]:.3f} s ({len(rows)} bad values)')
    return JointRecording(t_s=t[sel], names=names, position=rec['position'],
                          velocity=rec['velocity'], effort=rec['effort'], stamp0_ns=int(stamps[0]))


def joint_state_message(stamp_ns: int, names, position=(), velocity=(), effort=()):
    """A rosbags sensor_msgs/msg/JointState."""
    types = TYPESTORE.types
    stamp = types['builtin_interfaces/msg/Time'](sec=int(stamp_ns // 1_000_000_000),
                                                   nanosec=int(stamp_ns % 1_000_000_000))
    header = types['std_msgs/msg/Header'](stamp=stamp, frame_id='')
    return types[JOINT_STATE_TYPE](header=header, name=list(names),
                                   position=np.ascontiguousarray(position, dtype=np.float64),
                                   velocity=np.ascontiguousarray(velocity, dtype=np.float64),
                                   effort=np.ascontiguousarray(effort, dtype=np.float64))


def write_joint_recording(bag_path: str | Path, rec: JointRecording, storage: str = 'mcap',
                          receive_lag_s: float = 0.0) -> int:
    """Write ``rec`` as ``/joint_states`` of a new contract bag; returns the number of messages.

    Header stamps are ``stamp0_ns + t_s``; the bag (receive) time lags them by ``receive_lag_s``.
    """
    with RawBagWriter(bag_path, storage=storage) as writer:
        for i, t in enumerate(rec.t_s):
            stamp = int(rec.stamp0_ns + round(float(t) * 1e9))
            msg = joint_state_message(
                stamp, rec.names, rec.position[i],
                () if rec.velocity is None else rec.velocity[i],
                () if rec.effort is None else rec.effort[i])
            writer.write(JOINT_STATES, JOINT_STATE_TYPE, stamp + int(receive_lag_s * 1e9),
                         serialize(msg, JOINT_STATE_TYPE))
        return writer.count
