"""Smooth joint-space excitation: a sum of sines faded in and out, still at both ends.

q_ref(t) = q_start + w(t) s(t), with s_j(t) = A_j sum_i c_i sin(2 pi f_ij (t - t_rest) + phi_ij) / sum_i c_i and
w(t) a quintic smoothstep (C2) from 0 to 1 over ``ramp_s`` after ``rest_s`` seconds of stillness, back to 0 over
``ramp_s`` before the last ``end_rest_s`` seconds. Velocity and acceleration are exact derivatives.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Baxter right arm, gripper pointing down in front of the robot (CONTRACTS check pose).
BAXTER_RIGHT_NOMINAL_RAD = (0.0, -0.55, 0.0, 0.75, 0.0, 1.26, 0.0)


@dataclass
class SumOfSinesMotion:
    """Reference motion spec (SI units).

    amplitudes_rad: per-joint amplitude A_j (scalar: the same for all); frequencies_hz / weights: the sine
    components (each joint gets its frequencies scaled by (1 + detune * j) so joints are not in lock-step);
    phases from ``phase_seed``. q_start: the still pose at both ends (None: the simulator chooses, see
    mujoco_loop.simulate_loop_experiment); q_seed: nominal pose for that choice.
    """
    amplitudes_rad: tuple[float, ...] | float = (0.10, 0.08, 0.12, 0.10, 0.15, 0.12, 0.25)
    frequencies_hz: tuple[float, ...] = (0.13, 0.37, 0.83)
    weights: tuple[float, ...] = (1.0, 0.5, 0.25)
    detune: float = 0.07
    rest_s: float = 1.0
    ramp_s: float = 2.0
    end_rest_s: float = 0.5
    phase_seed: int = 7
    q_start: tuple[float, ...] | None = None
    q_seed: tuple[float, ...] | None = None


def _smoothstep(x):
    """Quintic 10x^3 - 15x^4 + 6x^5 on [0, 1] and its first two derivatives (w.r.t. x)."""
    x = np.clip(x, 0.0, 1.0)
    return (10 * x**3 - 15 * x**4 + 6 * x**5, 30 * x**2 - 60 * x**3 + 30 * x**4, 60 * x - 180 * x**2 + 120 * x**3)


def window(t: np.ndarray, duration_s: float, spec: SumOfSinesMotion):
    """w(t), w'(t), w''(t): 0 while still, 1 in the middle, C2 ramps."""
    t = np.asarray(t, dtype=float)
    ramp = spec.ramp_s
    up, dup, ddup = _smoothstep((t - spec.rest_s) / ramp)
    t_end = duration_s - spec.end_rest_s
    down, ddown, dddown = _smoothstep((t_end - t) / ramp)
    w = up * down
    dw = (dup * down - up * ddown) / ramp
    ddw = (ddup * down - 2 * dup * ddown + up * dddown) / ramp**2
    return w, dw, ddw


def reference(t: np.ndarray, q_start: np.ndarray, duration_s: float, spec: SumOfSinesMotion):
    """Joint reference at times ``t`` [s]: (q [rad], qd [rad/s], qdd [rad/s^2]), each (len(t), n)."""
    q_start = np.asarray(q_start, dtype=float)
    n = len(q_start)
    if duration_s < spec.rest_s + 2 * spec.ramp_s + spec.end_rest_s:
        raise ValueError(f'duration {duration_s} s is shorter than rest + 2 ramps + end rest '
                         f'({spec.rest_s} + 2 x {spec.ramp_s} + {spec.end_rest_s} s)')
    amp = np.broadcast_to(np.asarray(spec.amplitudes_rad, dtype=float), (n,)) \
        if np.ndim(spec.amplitudes_rad) == 0 else np.asarray(spec.amplitudes_rad, dtype=float)
    if amp.shape != (n,):
        raise ValueError(f'motion amplitudes have {len(amp)} values for {n} joints')
    freqs = np.asarray(spec.frequencies_hz, dtype=float)
    weights = np.asarray(spec.weights, dtype=float)
    if freqs.shape != weights.shape:
        raise ValueError('motion frequencies_hz and weights must have the same length')
    rng = np.random.default_rng(spec.phase_seed)
    phases = rng.uniform(0, 2 * np.pi, size=(n, len(freqs)))
    tau = np.asarray(t, dtype=float)[:, None, None] - spec.rest_s             # (K, 1, 1)
    omega = 2 * np.pi * freqs[None, :] * (1.0 + spec.detune * np.arange(n))[:, None]   # (n, m)
    arg = omega[None] * tau + phases[None]
    scale = (amp / weights.sum())[:, None] * weights[None, :]                 # (n, m)
    s = np.sum(scale * np.sin(arg), axis=2)
    ds = np.sum(scale * omega * np.cos(arg), axis=2)
    dds = -np.sum(scale * omega**2 * np.sin(arg), axis=2)
    w, dw, ddw = (v[:, None] for v in window(t, duration_s, spec))
    q = q_start[None, :] + w * s
    qd = dw * s + w * ds
    qdd = ddw * s + 2 * dw * ds + w * dds
    return q, qd, qdd
