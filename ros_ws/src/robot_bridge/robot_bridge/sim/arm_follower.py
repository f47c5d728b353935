"""A simulated arm (fake hardware) that executes joint trajectories: MuJoCo, real-time steppable, with sensor effects.

The arm (optionally holding the experiment's clamped flexible loop) is ``mujoco_loop.LoopSimulator``: the same
URDF -> MJCF model, the same computed-torque + PD controller on the arm's own rigid-body model (the controller knows
the arm, not the object or any added friction), the same undeclared effects (``mujoco_loop.Effects``: arm viscous
and Coulomb friction, loop damping, torque-sensor bias and gain, encoder and torque-sensor delays) and measurement
noise (``mujoco_loop.MeasurementNoise``). What this module adds: a joint reference that follows commanded
trajectories as they arrive, and measurements taken while the simulation runs.

Reference: a command (times from its start [s], positions, optional velocities) is interpolated by a cubic Hermite
spline (velocities given) or a C2 cubic spline with zero end velocities (not given), starting from the reference's
current position and velocity when the first point lies in the future (as ros2_control's joint_trajectory_controller
does); after the last point the reference holds it. A new command replaces the old one from the moment it starts.
``excitation`` is the alternative to a command: the example recordings' excitation (``motion.reference``: still
for ``rest_s``, the faded sum of sines, still again for ``end_rest_s``) from the current pose.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from .experiment import ExperimentSpec
from .mjcf_builder import Numerics
from .motion import SumOfSinesMotion, reference
from .mujoco_loop import Controller, Effects, LoopSimulator, MeasurementNoise, Settling, _per_joint


@dataclass
class JointReference:
    """q_ref(t), qd_ref(t), qdd_ref(t) for absolute simulation time t [s]: a spline from t0_s, held at the end."""
    t0_s: float
    spline: object
    t_end_s: float

    def __call__(self, t_s: float):
        tau = min(max(t_s - self.t0_s, 0.0), self.t_end_s - self.t0_s)
        q = self.spline(tau)
        if t_s <= self.t0_s or t_s >= self.t_end_s:     # before the start or after the end: hold still
            return q, np.zeros_like(q), np.zeros_like(q)
        return q, self.spline(tau, 1), self.spline(tau, 2)


@dataclass
class ExcitationReference:
    """``motion.reference`` of duration_s seconds from q_start, started at simulation time t0_s, held at the end."""
    t0_s: float
    q_start: np.ndarray
    duration_s: float
    motion: SumOfSinesMotion

    @property
    def t_end_s(self) -> float:
        return self.t0_s + self.duration_s

    def __call__(self, t_s: float):
        tau = min(max(t_s - self.t0_s, 0.0), self.duration_s)
        q, qd, qdd = reference(np.array([tau]), self.q_start, self.duration_s, self.motion)
        return q[0], qd[0], qdd[0]


def hold_reference(q, t_s: float) -> JointReference:
    q = np.asarray(q, dtype=float)
    return JointReference(t_s, CubicSpline([0.0, 1.0], np.stack([q, q]), bc_type='clamped'), t_s)


class ArmFollower:
    """LoopSimulator + a commanded joint reference + online measurements (see the module docstring)."""

    def __init__(self, experiment: ExperimentSpec, q_start=None, effects: Effects | None = None,
                 noise: MeasurementNoise | None = None, controller: Controller | None = None,
                 with_object: bool = False, k_theta: float = 5.0, k_phi: float = 3.0,
                 numerics: Numerics | None = None, seed: int = 0):
        self.effects = effects or Effects()
        self.noise = noise or MeasurementNoise()
        self.controller = controller or Controller()
        self.sim = LoopSimulator(experiment, k_theta, k_phi, self.effects.passive(), numerics or Numerics(),
                                 with_object)
        self.sim.gain_inertia_floor = self.controller.gain_inertia_floor_kgm2
        sim, n = self.sim, len(self.sim.arm_names)
        if q_start is None:
            q_start = sim.solve_start_pose() if sim.has_loop else sim.default_seed()
        q_start = np.asarray(q_start, dtype=float)
        if q_start.shape != (n,):
            raise ValueError(f'the start pose has {q_start.size} values for {n} arm joints {sim.arm_names}')
        sim.set_state(q_start)
        self.settle_info = sim.settle(q_start, self.controller, Settling(), self.effects.loop_damping_nms)
        self.dt = sim.model.opt.timestep
        self.t_s = 0.0
        self.reference = hold_reference(q_start, 0.0)
        self.bias = _per_joint(self.effects.effort_bias_nm, n, 'effort_bias_nm')
        self.rng = np.random.default_rng(seed)
        self.last_tau = self._control()       # the holding torque: what the torque sensors read before the first step
        keep = int(np.ceil(max(self.effects.position_delay_s, self.effects.effort_delay_s) / self.dt)) + 2
        self.history = deque(maxlen=keep)
        self._record()

    @property
    def joint_names(self) -> list[str]:
        return list(self.sim.arm_names)

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        d = self.sim.data
        return d.qpos[self.sim.arm_qpos].copy(), d.qvel[self.sim.arm_dof].copy()

    def command(self, times_s, positions, velocities=None, start_s: float | None = None):
        """Follow a trajectory starting at simulation time start_s (None: now). times_s (K,) from the start,
        increasing, >= 0; positions (K, n); velocities (K, n) or None. Raises ValueError on a malformed command."""
        t = np.asarray(times_s, dtype=float)
        q = np.asarray(positions, dtype=float)
        n = len(self.sim.arm_names)
        if t.ndim != 1 or len(t) == 0 or q.shape != (len(t), n):
            raise ValueError(f'a trajectory needs K >= 1 times and K x {n} positions, got {t.shape}, {q.shape}')
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))) or np.any(t < 0) or np.any(np.diff(t) <= 0):
            raise ValueError('trajectory times must be finite, >= 0 and increasing, positions finite')
        start = self.t_s if start_s is None else max(float(start_s), self.t_s)
        qd = None if velocities is None else np.asarray(velocities, dtype=float)
        if qd is not None and qd.shape != q.shape:
            qd = None
        if t[0] > 0.0:                        # lead in from where the reference is now
            q0, qd0, _ = self.reference(start)
            t, q = np.r_[0.0, t], np.vstack([q0, q])
            if qd is not None:
                qd = np.vstack([qd0, qd])
        if len(t) == 1:
            self.reference = hold_reference(q[0], start)
            return
        spline = (CubicHermiteSpline(t, q, qd) if qd is not None else CubicSpline(t, q, bc_type='clamped'))
        self.reference = JointReference(start - t[0], spline, start + (t[-1] - t[0]))

    def excitation(self, duration_s: float, motion: SumOfSinesMotion | None = None) -> ExcitationReference:
        """The excitation ``motion.reference`` (duration_s seconds in all, rests included) from the current reference
        pose, starting now; follow it with ``follower.reference = ...`` (its t0_s may be moved later). Raises
        ValueError if duration_s is too short for the motion's rests and ramps or the motion leaves the joint limits."""
        motion = motion or SumOfSinesMotion()
        q_start, _, _ = self.reference(self.t_s)
        sim = self.sim
        q = reference(np.linspace(0.0, duration_s, int(duration_s * 100) + 2), q_start, duration_s, motion)[0]
        outside = (q < sim.lower - 1e-9) | (q > sim.upper + 1e-9)
        if np.any(outside):
            j = int(np.nonzero(outside.any(axis=0))[0][0])
            raise ValueError(f'the excitation leaves the limits of {sim.arm_names[j]} [{sim.lower[j]}, {sim.upper[j]}]'
                             ': reduce its amplitude')
        return ExcitationReference(self.t_s, q_start, float(duration_s), motion)

    @property
    def trajectory_done(self) -> bool:
        return self.t_s >= self.reference.t_end_s

    def step(self, n_steps: int = 1):
        sim = self.sim
        for _ in range(n_steps):
            tau = self._control()
            sim.data.ctrl[sim.arm_act] = tau
            self.last_tau = tau
            mujoco.mj_step(sim.model, sim.data)
            self.t_s += self.dt
            if not np.all(np.isfinite(sim.data.qpos)):
                raise RuntimeError(f'the arm simulation diverged at t = {self.t_s:.3f} s')
            self._record()

    def _control(self) -> np.ndarray:
        """The actuator torques for the current state and reference (clipped to the effort limits)."""
        q_ref, qd_ref, qdd_ref = self.reference(self.t_s)
        tau_ff, mass = self.sim.inverse_dynamics(q_ref, qd_ref, qdd_ref)
        return self.sim.control(tau_ff[0], mass[0], q_ref, qd_ref, self.controller)

    def advance_to(self, t_s: float):
        """Step until the simulation time reaches t_s."""
        self.step(max(0, int(np.floor((t_s - self.t_s) / self.dt + 1e-9))))

    def _record(self):
        q, qd = self.state()
        self.history.append((self.t_s, q, qd, self.last_tau.copy()))

    def _delayed(self, index: int, delay_s: float) -> np.ndarray:
        if delay_s <= 0.0:
            return self.history[-1][index].copy()
        t_want = self.t_s - delay_s
        for t, *values in reversed(self.history):
            if t <= t_want + 1e-12:
                return np.asarray(values[index - 1]).copy()
        return np.asarray(self.history[0][index]).copy()

    def measure(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Measured (position [rad], velocity [rad/s], effort [N m]) now: the applied actuator torque as a joint
        torque sensor reads it (gain, bias), encoder / torque-sensor delays, noise."""
        e, nz = self.effects, self.noise
        q = self._delayed(1, e.position_delay_s)
        qd = self._delayed(2, e.position_delay_s)
        tau = e.effort_gain * self._delayed(3, e.effort_delay_s) + self.bias
        if nz.position_rad:
            q += self.rng.normal(0.0, nz.position_rad, q.shape)
        if nz.velocity_rad_s:
            qd += self.rng.normal(0.0, nz.velocity_rad_s, qd.shape)
        if nz.effort_nm:
            tau += self.rng.normal(0.0, nz.effort_nm, tau.shape)
        return q, qd, tau
