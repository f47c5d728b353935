"""Independent MuJoCo simulation of an arm handling the contract's closed flexible loop -> a contract joint log.

The experiment (CONTRACTS.md section 2) is built into MJCF by ``mjcf_builder`` (URDF inertias, URDF damping as joint
damping, gravity on every link; loop of N solid-cylinder links, Ry(theta) Rz(phi) joints with springs k_theta, k_phi,
both branch ends welded to the clamp). The arm follows a smooth sum-of-sines reference (``motion``) under a
computed-torque feed-forward from the arm's own rigid-body model (the controller knows the arm, not the object)
plus a PD loop shaped by the arm's mass matrix:

    tau = ID_arm(q_ref, qd_ref, qdd_ref) + M_arm(q_ref) (w^2 (q_ref - q) + 2 zeta w (qd_ref - qd)),

held constant over each timestep (1 kHz) and clipped to the URDF effort limits. The recorded ``effort`` is that
actuator torque (a joint torque sensor's reading); the URDF damping and any added friction act in addition.

Start state: the arm holds its start pose while the loop settles with temporary joint damping; the damping is then
removed (static equilibrium does not depend on it) and recording starts, so the first ``rest_s`` seconds are still.
With no object the default start pose is the nominal one; with the loop it is the pose (closest to the nominal
one) that puts the grasp frame at G = C T(0, 0, -2R), where the undeformed loop closes exactly.

Undeclared effects for testing model-error diagnosis (``Effects``): loop-joint viscous damping, arm viscous and
Coulomb friction, torque-sensor bias and gain, measurement delays of the joint encoders and of the torque sensors.
Measurement noise (``MeasurementNoise``) is Gaussian and seeded.

Command line (writes a contract bag)::

    python -m robot_bridge.sim.mujoco_loop --experiment EXP.yaml --out BAG --k-theta 5 --k-phi 3 [--duration 20]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from ..bagio.contract import JointRecording, write_joint_recording
from .experiment import ExperimentSpec, load_experiment
from .mjcf_builder import BuiltModel, Numerics, PassiveEffects, build_mjcf
from .motion import BAXTER_RIGHT_NOMINAL_RAD, SumOfSinesMotion, reference
from .transforms import rotation_angle, transform

DEFAULT_STAMP0_NS = 1_700_000_000_000_000_000


@dataclass
class Effects(PassiveEffects):
    """Everything the declared model lacks (defaults: none). Physical (see PassiveEffects) plus sensor effects:

    effort_bias_nm: constant torque-sensor offset added to every recorded effort [N m] (scalar or per joint);
    effort_gain: torque-sensor gain (recorded = gain * true + bias);
    position_delay_s: joint encoders (position and velocity) report the motion this late [s];
    effort_delay_s: torque sensors report the applied torque this late [s].
    """
    effort_bias_nm: float | list[float] = 0.0
    effort_gain: float = 1.0
    position_delay_s: float = 0.0
    effort_delay_s: float = 0.0

    def passive(self) -> PassiveEffects:
        return PassiveEffects(self.loop_damping_nms, self.arm_viscous_nms, self.arm_coulomb_nm)


@dataclass
class MeasurementNoise:
    """Standard deviations of additive Gaussian measurement noise (0: none)."""
    position_rad: float = 0.0
    velocity_rad_s: float = 0.0
    effort_nm: float = 0.0


@dataclass
class Controller:
    """Computed-torque + PD tracking: closed-loop bandwidth [rad/s] and damping ratio of the arm-only error dynamics.

    The PD gains are shaped by M_arm(q_ref) + gain_inertia_floor_kgm2 * I, so that light distal joints (Baxter's
    w2 alone has 6e-4 kg m^2) still hold against the object.
    """
    bandwidth_rad_s: float = 40.0
    damping_ratio: float = 1.0
    gain_inertia_floor_kgm2: float = 0.01


@dataclass
class Settling:
    """Start-state settling: temporary loop damping [N m s/rad], velocity tolerance [rad/s], time limit [s]."""
    loop_damping_nms: float = 0.05
    velocity_tol_rad_s: float = 1e-7
    max_time_s: float = 60.0


@dataclass
class LoopRecording(JointRecording):
    """A JointRecording (the measured, possibly noisy/delayed arm log) plus the simulator's ground truth.

    loop_names / loop_position: loop joint angles [rad] in the contract's configuration order (left branch
    theta_1, phi_1, ..., then right); arm_position_true / arm_velocity_true / effort_true: noise- and delay-free;
    grasp_position_m: G's origin in the base frame; weld_residual_m / weld_residual_rad: the larger of the two
    branch ends' distance / angle from their clamp targets at each sample; info: settings and summary numbers.
    """
    loop_names: list[str] = field(default_factory=list)
    loop_position: np.ndarray | None = None
    arm_position_true: np.ndarray | None = None
    arm_velocity_true: np.ndarray | None = None
    effort_true: np.ndarray | None = None
    grasp_position_m: np.ndarray | None = None
    weld_residual_m: np.ndarray | None = None
    weld_residual_rad: np.ndarray | None = None
    info: dict = field(default_factory=dict)

    def joint_recording(self) -> JointRecording:
        """Just the measured log, as a plain JointRecording."""
        return JointRecording(self.t_s, list(self.names), self.position, self.velocity, self.effort, self.stamp0_ns)


def _per_joint(value, n: int, what: str) -> np.ndarray:
    arr = np.full(n, float(value)) if np.ndim(value) == 0 else np.asarray(value, dtype=float)
    if arr.shape != (n,):
        raise ValueError(f'{what} needs 1 or {n} values, got {len(arr)}')
    return arr


def _coerce(cls, value):
    """A dataclass instance from an instance, a dict of its fields or None (defaults)."""
    if value is None:
        return cls()
    if isinstance(value, cls):
        return value
    if isinstance(value, dict):
        unknown = set(value) - set(cls.__dataclass_fields__)
        if unknown:
            raise ValueError(f'{cls.__name__} has no field(s) {sorted(unknown)}; '
                             f'known: {sorted(cls.__dataclass_fields__)}')
        return cls(**value)
    raise ValueError(f'expected {cls.__name__} or a dict, got {type(value).__name__}')


class LoopSimulator:
    """The compiled MuJoCo model of one experiment plus the index bookkeeping (arm/loop joints, sites)."""

    def __init__(self, experiment: ExperimentSpec, k_theta: float = 1.0, k_phi: float = 1.0,
                 effects: PassiveEffects | None = None, numerics: Numerics | None = None, with_object: bool = True):
        self.experiment = experiment
        self.numerics = numerics or Numerics()
        self.has_loop = with_object and experiment.loop is not None
        self.built: BuiltModel = build_mjcf(experiment, k_theta, k_phi, effects, self.numerics, self.has_loop)
        self.model = mujoco.MjModel.from_xml_string(self.built.xml)
        self.data = mujoco.MjData(self.model)
        self.gain_inertia_floor = 0.0
        # The controller's own model: the same arm, no object, no undeclared effects.
        arm_only = build_mjcf(experiment, numerics=self.numerics, with_object=False)
        self.arm_model = mujoco.MjModel.from_xml_string(arm_only.xml)
        self.arm_data = mujoco.MjData(self.arm_model)
        m = self.model
        self.arm_names = list(experiment.arm.joints)
        self.arm_qpos = np.array([m.jnt_qposadr[m.joint(n).id] for n in self.arm_names])
        self.arm_dof = np.array([m.jnt_dofadr[m.joint(n).id] for n in self.arm_names])
        self.arm_act = np.array([m.actuator(f'motor_{n}').id for n in self.arm_names])
        am = self.arm_model
        self.ctrl_qpos = np.array([am.jnt_qposadr[am.joint(n).id] for n in self.arm_names])
        self.ctrl_dof = np.array([am.jnt_dofadr[am.joint(n).id] for n in self.arm_names])
        self.loop_names = list(self.built.loop_joints)
        self.loop_qpos = np.array([m.jnt_qposadr[m.joint(n).id] for n in self.loop_names], dtype=int)
        self.loop_dof = np.array([m.jnt_dofadr[m.joint(n).id] for n in self.loop_names], dtype=int)
        urdf_joints = self.built.urdf.joints
        self.lower = np.array([urdf_joints[n].lower if urdf_joints[n].lower is not None else -np.inf
                               for n in self.arm_names])
        self.upper = np.array([urdf_joints[n].upper if urdf_joints[n].upper is not None else np.inf
                               for n in self.arm_names])
        self.effort_limit = np.array([urdf_joints[n].effort if urdf_joints[n].effort else np.inf
                                      for n in self.arm_names])
        self.grasp_site = m.site('grasp').id
        self.end_sites = ([(m.site(f'loop_{s}_end').id, m.site(f'clamp_{s}').id) for s in ('left', 'right')]
                          if self.has_loop else [])

    # -- kinematics -------------------------------------------------------------------------------------
    def arm_grasp_pose(self, q_arm) -> np.ndarray:
        """G (4x4, base frame) for arm joint angles q_arm, from the controller's arm-only model."""
        d = self.arm_data
        d.qpos[self.ctrl_qpos] = q_arm
        mujoco.mj_kinematics(self.arm_model, d)
        s = self.arm_model.site('grasp').id
        return transform(d.site_xmat[s].reshape(3, 3), d.site_xpos[s])

    def weld_residual(self) -> tuple[float, float]:
        """Largest branch-end distance [m] and angle [rad] from the clamp targets, at the current kinematics."""
        d, dist, ang = self.data, 0.0, 0.0
        for end, clamp in self.end_sites:
            dist = max(dist, float(np.linalg.norm(d.site_xpos[end] - d.site_xpos[clamp])))
            ang = max(ang, rotation_angle(d.site_xmat[end].reshape(3, 3).T @ d.site_xmat[clamp].reshape(3, 3)))
        return dist, ang

    def default_seed(self) -> np.ndarray:
        if self.arm_names == ['right_s0', 'right_s1', 'right_e0', 'right_e1', 'right_w0', 'right_w1', 'right_w2']:
            return np.array(BAXTER_RIGHT_NOMINAL_RAD)
        return np.clip(np.zeros(len(self.arm_names)), self.lower, self.upper)

    def solve_start_pose(self, q_seed=None) -> np.ndarray:
        """Arm angles (within limits, near q_seed) that put G at the rest-shape pose C T(0, 0, -2R).

        Raises ValueError if the clamp is out of reach (pose error above 1e-9 m).
        """
        from scipy.optimize import least_squares
        target = self.experiment.loop.rest_grasp()
        seed = self.default_seed() if q_seed is None else np.asarray(q_seed, dtype=float)
        lo = np.where(np.isfinite(self.lower), self.lower + 1e-3, -np.inf)
        hi = np.where(np.isfinite(self.upper), self.upper - 1e-3, np.inf)
        seed = np.clip(seed, lo + 1e-9, hi - 1e-9)

        points = np.array([[0.0, 0.0, 0.0, 1.0], [0.1, 0.0, 0.0, 1.0], [0.0, 0.1, 0.0, 1.0]]).T

        def pose_error(q):   # three points of the frame (origin, 0.1 m along x and y): smooth, in metres
            return ((self.arm_grasp_pose(q) - target) @ points)[:3].ravel()

        coarse = least_squares(lambda q: np.r_[pose_error(q), 1e-3 * (q - seed)], seed, bounds=(lo, hi),
                               xtol=1e-15, ftol=1e-15, gtol=1e-15)
        fine = least_squares(pose_error, coarse.x, bounds=(lo, hi), xtol=1e-15, ftol=1e-15, gtol=1e-15)
        err = pose_error(fine.x)
        if np.max(np.abs(err)) > 1e-9:
            raise ValueError(f'the clamp pose is out of the arm\'s reach: no start pose puts the grasp frame at '
                             f'C T(0, 0, -2R) = {np.round(target[:3, 3], 4).tolist()} (residual '
                             f'{np.max(np.abs(err)):.3g}); pass motion.q_start explicitly or move the clamp')
        return fine.x

    # -- dynamics ---------------------------------------------------------------------------------------
    def set_state(self, q_arm, q_loop=None, qd_arm=None, qd_loop=None):
        d = self.data
        mujoco.mj_resetData(self.model, d)
        d.qpos[self.arm_qpos] = q_arm
        if q_loop is not None:
            d.qpos[self.loop_qpos] = q_loop
        if qd_arm is not None:
            d.qvel[self.arm_dof] = qd_arm
        if qd_loop is not None:
            d.qvel[self.loop_dof] = qd_loop
        mujoco.mj_forward(self.model, d)

    def inverse_dynamics(self, q, qd, qdd) -> tuple[np.ndarray, np.ndarray]:
        """Arm-only model: joint torques for (q, qd, qdd) (rows) and the gain-shaping mass matrices (K, n, n):
        M_arm(q) + gain_inertia_floor I."""
        am, ad = self.arm_model, self.arm_data
        q, qd, qdd = np.atleast_2d(q), np.atleast_2d(qd), np.atleast_2d(qdd)
        k, n = q.shape
        tau, mass = np.empty((k, n)), np.empty((k, n, n))
        full = np.empty((am.nv, am.nv))
        for i in range(k):
            ad.qpos[self.ctrl_qpos], ad.qvel[self.ctrl_dof], ad.qacc[self.ctrl_dof] = q[i], qd[i], qdd[i]
            mujoco.mj_inverse(am, ad)
            tau[i] = ad.qfrc_inverse[self.ctrl_dof]
            mujoco.mj_fullM(am, ad, full)
            mass[i] = full[np.ix_(self.ctrl_dof, self.ctrl_dof)]
        mass += self.gain_inertia_floor * np.eye(n)
        return tau, mass

    def control(self, tau_ff, mass, q_ref, qd_ref, gains: Controller) -> np.ndarray:
        d = self.data
        w, z = gains.bandwidth_rad_s, gains.damping_ratio
        err = q_ref - d.qpos[self.arm_qpos]
        derr = qd_ref - d.qvel[self.arm_dof]
        tau = tau_ff + mass @ (w * w * err + 2.0 * z * w * derr)
        return np.clip(tau, -self.effort_limit, self.effort_limit)

    def settle(self, q_hold, gains: Controller, settling: Settling, loop_damping_after: float) -> dict:
        """Hold q_hold until everything is still (temporary loop damping), then restore the loop damping."""
        m, d = self.model, self.data
        if len(self.loop_dof):
            m.dof_damping[self.loop_dof] = max(settling.loop_damping_nms, loop_damping_after)
        zeros = np.zeros(len(q_hold))
        tau_ff, mass = self.inverse_dynamics(q_hold, zeros, zeros)
        dt = m.opt.timestep
        steps, still_steps, needed = 0, 0, max(1, int(round(0.1 / dt)))
        max_steps = int(round(settling.max_time_s / dt))
        while steps < max_steps:
            d.ctrl[self.arm_act] = self.control(tau_ff[0], mass[0], q_hold, zeros, gains)
            mujoco.mj_step(m, d)
            steps += 1
            still_steps = still_steps + 1 if np.max(np.abs(d.qvel)) < settling.velocity_tol_rad_s else 0
            if still_steps >= needed:
                break
        if len(self.loop_dof):
            m.dof_damping[self.loop_dof] = loop_damping_after
        mujoco.mj_forward(m, d)
        return {'settle_time_s': steps * dt, 'settled': still_steps >= needed,
                'settle_max_speed_rad_s': float(np.max(np.abs(d.qvel)))}


def _delayed(history: np.ndarray, t_hist: np.ndarray, t: np.ndarray, delay_s: float) -> np.ndarray:
    """history (len(t_hist), n) sampled at t_hist, read at t - delay (held at the first value before t_hist[0])."""
    if delay_s == 0.0:
        idx = np.searchsorted(t_hist, t - 1e-12)
        return history[idx]
    tq = np.clip(t - delay_s, t_hist[0], t_hist[-1])
    return np.stack([np.interp(tq, t_hist, history[:, j]) for j in range(history.shape[1])], axis=1)


def simulate_loop_experiment(experiment: dict | str | Path | ExperimentSpec, duration_s: float = 20.0,
                             k_theta: float = 5.0, k_phi: float = 3.0, seed: int = 0,
                             noise: MeasurementNoise | dict | None = None, effects: Effects | dict | None = None,
                             motion: SumOfSinesMotion | dict | None = None, rate_hz: float = 100.0,
                             numerics: Numerics | dict | None = None, controller: Controller | dict | None = None,
                             settling: Settling | dict | None = None, with_object: bool = True,
                             stamp0_ns: int = DEFAULT_STAMP0_NS) -> LoopRecording:
    """Simulate the experiment and return the recorded arm joint log (+ ground truth), see the module docstring.

    experiment: the contract YAML (path), its parsed dict (paths relative to the working directory) or an
    ExperimentSpec. duration_s: recording length [s]; samples at t = 0, 1/rate_hz, ... (duration_s * rate_hz of them).
    k_theta, k_phi: true loop spring constants [N m/rad]. seed: measurement-noise seed.
    with_object=False (or an experiment without ``object``) simulates the arm alone.
    """
    wall0 = time.perf_counter()
    exp = experiment if isinstance(experiment, ExperimentSpec) else load_experiment(experiment)
    noise, effects = _coerce(MeasurementNoise, noise), _coerce(Effects, effects)
    motion, numerics = _coerce(SumOfSinesMotion, motion), _coerce(Numerics, numerics)
    controller, settling = _coerce(Controller, controller), _coerce(Settling, settling)
    if not (k_theta > 0 and k_phi > 0):
        raise ValueError(f'k_theta and k_phi must be positive, got {k_theta}, {k_phi}')
    sim = LoopSimulator(exp, k_theta, k_phi, effects.passive(), numerics, with_object)
    sim.gain_inertia_floor = controller.gain_inertia_floor_kgm2
    n = len(sim.arm_names)
    dt = numerics.timestep_s
    per_sample = int(round(1.0 / (rate_hz * dt)))
    if abs(per_sample * dt * rate_hz - 1.0) > 1e-9:
        raise ValueError(f'the recording period 1/{rate_hz} s is not a whole number of {dt} s timesteps')
    n_samples = int(round(duration_s * rate_hz))
    n_steps = n_samples * per_sample

    # start pose
    if motion.q_start is not None:
        q_start = np.asarray(motion.q_start, dtype=float)
    elif sim.has_loop:
        q_start = sim.solve_start_pose(motion.q_seed)
    else:
        q_start = sim.default_seed() if motion.q_seed is None else np.asarray(motion.q_seed, dtype=float)
    if q_start.shape != (n,):
        raise ValueError(f'start pose has {q_start.size} values for {n} arm joints')

    # reference at every timestep, its feed-forward torques and mass matrices (the controller's arm model)
    t_steps = np.arange(n_steps + 1) * dt
    q_ref, qd_ref, qdd_ref = reference(t_steps, q_start, n_steps * dt, motion)
    outside = (q_ref < sim.lower - 1e-9) | (q_ref > sim.upper + 1e-9)
    if np.any(outside):
        j = int(np.nonzero(outside.any(axis=0))[0][0])
        raise ValueError(f'the reference leaves the limits of {sim.arm_names[j]} '
                         f'[{sim.lower[j]}, {sim.upper[j]}]: range {q_ref[:, j].min():.3f}..{q_ref[:, j].max():.3f}'
                         ' rad; reduce the motion amplitudes or change the start pose')
    tau_ff, mass = sim.inverse_dynamics(q_ref, qd_ref, qdd_ref)

    # static equilibrium at the start
    sim.set_state(q_start)
    initial_residual = sim.weld_residual() if sim.has_loop else (0.0, 0.0)
    if initial_residual[0] > 1e-3:
        warnings.warn(f'with the given start pose the undeformed loop misses the clamp by {initial_residual[0]:.3f} m; '
                      'the welds pull it shut while settling (leave motion.q_start unset to start exactly closed)')
    info = sim.settle(q_start, controller, settling, effects.loop_damping_nms)
    if not info['settled']:
        warnings.warn(f'not still after {settling.max_time_s} s of settling (max speed '
                      f'{info["settle_max_speed_rad_s"]:.2g} rad/s): the recording does not start at rest')

    # run, keeping every timestep's state and torque (for delays) and the ground truth at the samples
    m, d = sim.model, sim.data
    hist_q, hist_qd, hist_tau = np.empty((n_steps + 1, n)), np.empty((n_steps + 1, n)), np.empty((n_steps + 1, n))
    loop_q = np.empty((n_samples, len(sim.loop_qpos)))
    grasp = np.empty((n_samples, 3))
    weld_m, weld_rad = np.zeros(n_samples), np.zeros(n_samples)
    saturated = 0
    for i in range(n_steps + 1):
        hist_q[i], hist_qd[i] = d.qpos[sim.arm_qpos], d.qvel[sim.arm_dof]
        tau = sim.control(tau_ff[i], mass[i], q_ref[i], qd_ref[i], controller)
        saturated += int(np.any(np.abs(tau) >= sim.effort_limit))
        hist_tau[i] = tau
        if i % per_sample == 0 and i // per_sample < n_samples:
            k = i // per_sample
            mujoco.mj_kinematics(m, d)
            loop_q[k] = d.qpos[sim.loop_qpos]
            grasp[k] = d.site_xpos[sim.grasp_site]
            if sim.has_loop:
                weld_m[k], weld_rad[k] = sim.weld_residual()
        if i == n_steps:
            break
        d.ctrl[sim.arm_act] = tau
        mujoco.mj_step(m, d)
        if not np.all(np.isfinite(d.qpos)):
            raise RuntimeError(f'simulation diverged at t = {i * dt:.3f} s; try a smaller timestep')

    t = np.arange(n_samples) / rate_hz
    idx = np.arange(n_samples) * per_sample
    q_true, qd_true, tau_true = hist_q[idx], hist_qd[idx], hist_tau[idx]
    q_meas = _delayed(hist_q, t_steps, t, effects.position_delay_s)
    qd_meas = _delayed(hist_qd, t_steps, t, effects.position_delay_s)
    tau_meas = _delayed(hist_tau, t_steps, t, effects.effort_delay_s)
    tau_meas = effects.effort_gain * tau_meas + _per_joint(effects.effort_bias_nm, n, 'effort_bias_nm')
    rng = np.random.default_rng(seed)
    q_meas = q_meas + rng.normal(0.0, noise.position_rad, q_meas.shape) if noise.position_rad else q_meas
    qd_meas = qd_meas + rng.normal(0.0, noise.velocity_rad_s, qd_meas.shape) if noise.velocity_rad_s else qd_meas
    tau_meas = tau_meas + rng.normal(0.0, noise.effort_nm, tau_meas.shape) if noise.effort_nm else tau_meas

    info.update({
        'k_theta': float(k_theta), 'k_phi': float(k_phi), 'seed': int(seed), 'rate_hz': float(rate_hz),
        'duration_s': float(duration_s), 'with_object': bool(sim.has_loop),
        'loop_links': exp.loop.links if sim.has_loop else 0,
        'effects': asdict(effects), 'noise': asdict(noise), 'motion': asdict(motion), 'numerics': asdict(numerics),
        'controller': asdict(controller), 'q_start_rad': q_start.tolist(),
        'initial_weld_residual_m': float(initial_residual[0]),
        'max_weld_residual_m': float(weld_m.max()), 'max_weld_residual_rad': float(weld_rad.max()),
        'saturated_steps': saturated, 'max_tracking_error_rad': float(np.max(np.abs(hist_q - q_ref))),
        'locked_joints': sim.built.locked_joints, 'wall_time_s': time.perf_counter() - wall0,
        'mujoco_version': mujoco.__version__,
    })
    return LoopRecording(
        t_s=t, names=list(sim.arm_names), position=q_meas, velocity=qd_meas, effort=tau_meas, stamp0_ns=stamp0_ns,
        loop_names=sim.loop_names, loop_position=loop_q, arm_position_true=q_true, arm_velocity_true=qd_true,
        effort_true=tau_true, grasp_position_m=grasp, weld_residual_m=weld_m, weld_residual_rad=weld_rad, info=info)


def save_truth(path: str | Path, rec: LoopRecording):
    """Ground truth beside a bag: ``<path>.json`` (settings, summary) and ``<path>.npz`` (true states, float32)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.with_suffix('.json').write_text(json.dumps(rec.info, indent=2) + '\n')
    arrays = {'t_s': rec.t_s, 'arm_position': rec.arm_position_true, 'arm_velocity': rec.arm_velocity_true,
              'effort': rec.effort_true, 'loop_position': rec.loop_position, 'grasp_position_m': rec.grasp_position_m}
    np.savez_compressed(path.with_suffix('.npz'), arm_names=np.array(rec.names), loop_names=np.array(rec.loop_names),
                        **{k: np.asarray(v, dtype=np.float32) for k, v in arrays.items()})


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='python -m robot_bridge.sim.mujoco_loop', description=__doc__.split('\n')[0])
    p.add_argument('--experiment', required=True, help='experiment YAML (CONTRACTS.md section 2)')
    p.add_argument('--out', required=True, help='bag directory to create')
    p.add_argument('--k-theta', type=float, default=5.0, help='true in-plane loop stiffness [N m/rad]')
    p.add_argument('--k-phi', type=float, default=3.0, help='true out-of-plane loop stiffness [N m/rad]')
    p.add_argument('--duration', type=float, default=20.0, help='recording length [s]')
    p.add_argument('--rate', type=float, default=100.0, help='recording rate [Hz]')
    p.add_argument('--seed', type=int, default=0, help='measurement-noise seed')
    p.add_argument('--storage', choices=['mcap', 'sqlite3'], default='mcap')
    p.add_argument('--no-object', action='store_true', help='simulate the arm alone')
    g = p.add_argument_group('measurement noise (standard deviations)')
    g.add_argument('--noise-position', type=float, default=0.0, metavar='RAD')
    g.add_argument('--noise-velocity', type=float, default=0.0, metavar='RAD_S')
    g.add_argument('--noise-effort', type=float, default=0.0, metavar='NM')
    g = p.add_argument_group('undeclared effects')
    g.add_argument('--loop-damping', type=float, default=0.0, help='loop joint viscous damping [N m s/rad]')
    g.add_argument('--arm-viscous', type=float, nargs='+', default=[0.0],
                   help='extra arm viscous friction [N m s/rad] (one value, or one per arm joint)')
    g.add_argument('--arm-coulomb', type=float, nargs='+', default=[0.0],
                   help='arm Coulomb friction [N m] (one value, or one per arm joint)')
    g.add_argument('--effort-bias', type=float, nargs='+', default=[0.0], help='torque-sensor bias [N m]')
    g.add_argument('--effort-gain', type=float, default=1.0, help='torque-sensor gain')
    g.add_argument('--position-delay', type=float, default=0.0, help='encoder delay [s]')
    g.add_argument('--effort-delay', type=float, default=0.0, help='torque-sensor delay [s]')
    g = p.add_argument_group('motion and numerics')
    g.add_argument('--amplitude-scale', type=float, default=1.0, help='scale the default motion amplitudes')
    g.add_argument('--timestep', type=float, default=1e-3, help='simulation timestep [s]')
    g.add_argument('--integrator', default='RK4', choices=['RK4', 'implicit', 'implicitfast', 'Euler'])
    p.add_argument('--truth', help='also write ground truth to TRUTH.json / TRUTH.npz')
    p.add_argument('--dump-mjcf', help='write the generated MuJoCo XML here')
    return p


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    def one_or_per_joint(values):
        return values[0] if len(values) == 1 else values

    effects = Effects(loop_damping_nms=args.loop_damping, arm_viscous_nms=one_or_per_joint(args.arm_viscous),
                      arm_coulomb_nm=one_or_per_joint(args.arm_coulomb),
                      effort_bias_nm=one_or_per_joint(args.effort_bias), effort_gain=args.effort_gain,
                      position_delay_s=args.position_delay, effort_delay_s=args.effort_delay)
    default = SumOfSinesMotion()
    motion = SumOfSinesMotion(amplitudes_rad=tuple(args.amplitude_scale * np.asarray(default.amplitudes_rad)))
    try:
        if Path(args.out).exists():
            raise ValueError(f'{args.out} exists; choose a new bag directory')
        numerics = Numerics(timestep_s=args.timestep, integrator=args.integrator)
        rec = simulate_loop_experiment(
            args.experiment, args.duration, args.k_theta, args.k_phi, seed=args.seed,
            noise=MeasurementNoise(args.noise_position, args.noise_velocity, args.noise_effort), effects=effects,
            motion=motion, rate_hz=args.rate, numerics=numerics, with_object=not args.no_object)
        if args.dump_mjcf:
            sim = LoopSimulator(load_experiment(args.experiment), args.k_theta, args.k_phi, effects.passive(),
                                numerics, with_object=not args.no_object)
            Path(args.dump_mjcf).write_text(sim.built.xml)
    except ValueError as exc:
        print(f'mujoco_loop: error: {exc}', file=sys.stderr)
        return 1
    count = write_joint_recording(args.out, rec.joint_recording(), storage=args.storage)
    if args.truth:
        save_truth(args.truth, rec)
    i = rec.info
    print(f'{args.out}: {count} /joint_states messages, {args.duration} s at {args.rate} Hz; '
          f'settled in {i["settle_time_s"]:.2f} s; max weld residual {i["max_weld_residual_m"]:.2e} m / '
          f'{i["max_weld_residual_rad"]:.2e} rad; {i["wall_time_s"]:.1f} s wall time')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
