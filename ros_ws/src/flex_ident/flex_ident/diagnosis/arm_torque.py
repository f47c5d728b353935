"""The closed loop for an arm alone (no object): find what the URDF model of the arm lacks, in the torque domain.

Residual: measured joint effort minus the model's inverse dynamics (Pinocchio RNEA on the URDF, plus the URDF's
declared ``<dynamics damping>``) along the measured motion. Joint velocities and accelerations come from a
Savitzky-Golay filter (cubic) on a uniform time grid: it differentiates a local polynomial fit, so it is zero-phase
and does not amplify the encoder noise the way finite differences do (a causal filter would delay the derivatives
against the torques and read as a sensor delay). Its window is chosen from the data (:func:`choose_window`): the
one of 25, 50, 100, 200 ms that leaves the smallest nominal residual on the fitted part (too short lets encoder and
time-stamp noise into the accelerations, too long flattens the real motion).

Candidate effects (each a block of regressor columns, linear in its parameters, so a fit is a least-squares
problem): viscous and Coulomb friction (smooth sign tanh(qdot / 0.02 rad/s)), each shared by all joints or per joint;
a torque offset per joint; a torque-sensor gain per joint; a delay between torque and encoder channels (first order:
-delta d tau / dt); and errors of the inertial parameters (the base parameters of Pinocchio's joint-torque regressor
``computeJointTorqueRegressor``, found by a pivoted QR of the stacked regressor). The recording is split in time: the
first part (``1 - validation_fraction``) is fitted, the last part is never fitted and decides: effects are added one
at a time (the one that lowers the validation error most), while the validation RMS drops by at least
``min_gain`` (relative) and is still above the noise the torque signal itself shows (:func:`torque_noise_rms`:
what a smoothing of the measured torques leaves, corrected for the part of the noise the smoother keeps) by more
than ``noise_margin``: below that there is nothing left to explain. Shared and per-joint variants of a friction
compete; the data decide.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import savgol_filter

COULOMB_SMOOTHING_RAD_S = 0.02


class ArmDiagnosisError(ValueError):
    """Input that cannot give a meaningful torque-domain diagnosis (one clear message, no report)."""


@dataclass
class ArmSignals:
    t_s: np.ndarray
    q: np.ndarray            # (N, n) rad (smoothed)
    qd: np.ndarray           # (N, n) rad/s
    qdd: np.ndarray          # (N, n) rad/s^2
    tau: np.ndarray          # (N, n) measured N m (not smoothed)
    names: list
    dt: float
    window_samples: int


def smooth_derivatives(t_s, q, tau, names, window_s=0.051, order=3) -> ArmSignals:
    """Uniform grid (median step), then Savitzky-Golay position, velocity and acceleration."""
    t_s = np.asarray(t_s, float)
    dt = float(np.median(np.diff(t_s)))
    n = int(math.floor((t_s[-1] - t_s[0]) / dt + 1e-9)) + 1
    tu = t_s[0] + dt * np.arange(n)
    qu = np.column_stack([np.interp(tu, t_s, q[:, j]) for j in range(q.shape[1])])
    tauu = np.column_stack([np.interp(tu, t_s, tau[:, j]) for j in range(tau.shape[1])])
    w = max(order + 2, int(round(window_s / dt)) | 1)
    if w >= n:
        raise ArmDiagnosisError(f'the recording ({n} samples) is shorter than the differentiation window ({w})')
    qs = savgol_filter(qu, w, order, axis=0, mode='interp')
    qd = savgol_filter(qu, w, order, deriv=1, delta=dt, axis=0, mode='interp')
    qdd = savgol_filter(qu, w, order, deriv=2, delta=dt, axis=0, mode='interp')
    cut = w // 2                                    # the filter's edges are extrapolations: drop them
    sl = slice(cut, n - cut)
    return ArmSignals(tu[sl], qs[sl], qd[sl], qdd[sl], tauu[sl], list(names), dt, w)


WINDOWS_S = (0.025, 0.05, 0.1, 0.2)


def choose_window(t_s, q, tau, names, arm, validation_fraction=0.3):
    """The differentiation window with the smallest nominal torque residual on the fitted part of the recording."""
    best = None
    for w in WINDOWS_S:
        try:
            sig = smooth_derivatives(t_s, q, tau, names, window_s=w)
        except ArmDiagnosisError:
            continue
        n_fit = len(sig.t_s) - int(round(validation_fraction * len(sig.t_s)))
        r = sig.tau[:n_fit] - arm.inverse_dynamics(sig.q[:n_fit], sig.qd[:n_fit], sig.qdd[:n_fit])
        rms = _rms(r)
        if best is None or rms < best[0]:
            best = (rms, sig)
    if best is None:
        raise ArmDiagnosisError(f'the recording ({len(t_s)} samples) is too short to differentiate')
    return best[1]


class PinocchioArm:
    """The URDF arm reduced to ``joints`` (others locked at 0), gravity expressed in the URDF root frame."""

    def __init__(self, urdf_path, joints, base_link, gravity_base=(0.0, 0.0, -9.81)):
        import pinocchio as pin
        self.pin = pin
        try:
            full = pin.buildModelFromUrdf(str(urdf_path))
        except Exception as e:   # noqa: BLE001 - pinocchio raises plain exceptions for bad files
            raise ArmDiagnosisError(f'cannot read URDF {urdf_path}: {e}') from None
        names = list(full.names)
        missing = [j for j in joints if j not in names]
        if missing:
            raise ArmDiagnosisError(f'URDF {urdf_path} has no joint(s) {missing}')
        lock = [full.getJointId(n) for n in names[1:] if n not in joints]
        self.model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
        self.data = self.model.createData()
        order = [self.model.getJointId(j) for j in joints]
        self.idx_q = np.array([self.model.joints[i].idx_q for i in order])
        self.idx_v = np.array([self.model.joints[i].idx_v for i in order])
        if self.model.nv != len(joints):
            raise ArmDiagnosisError(f'only revolute/prismatic arm joints are supported ({joints})')
        R = np.eye(3)
        if self.model.existFrame(base_link):
            pin.framesForwardKinematics(self.model, self.data, pin.neutral(self.model))
            R = self.data.oMf[self.model.getFrameId(base_link)].rotation
        self.model.gravity.linear = R @ np.asarray(gravity_base, float)
        self.damping = np.asarray(self.model.damping, float)[self.idx_v]
        self.n_inertial = 10 * (self.model.njoints - 1)

    def _vec(self, x, idx, size):
        out = np.zeros(size)
        out[idx] = x
        return out

    def inverse_dynamics(self, q, qd, qdd):
        pin = self.pin
        out = np.empty_like(q)
        for k in range(len(q)):
            tau = pin.rnea(self.model, self.data, self._vec(q[k], self.idx_q, self.model.nq),
                           self._vec(qd[k], self.idx_v, self.model.nv), self._vec(qdd[k], self.idx_v, self.model.nv))
            out[k] = tau[self.idx_v]
        return out + self.damping * qd

    def torque_regressor(self, q, qd, qdd):
        """(N, n, 10 njoints): tau = Y theta, theta the inertial parameters of every body."""
        pin = self.pin
        Y = np.empty((len(q), len(self.idx_v), self.n_inertial))
        for k in range(len(q)):
            R = pin.computeJointTorqueRegressor(self.model, self.data,
                                                self._vec(q[k], self.idx_q, self.model.nq),
                                                self._vec(qd[k], self.idx_v, self.model.nv),
                                                self._vec(qdd[k], self.idx_v, self.model.nv))
            Y[k] = R[self.idx_v]
        return Y

    def link_of_joint(self, joint_id: int) -> str:
        """The URDF link a Pinocchio joint moves (the first body frame on it; links fixed to it are lumped in)."""
        for f in self.model.frames:
            parent = f.parentJoint if hasattr(f, 'parentJoint') else f.parent
            if f.type == self.pin.FrameType.BODY and parent == joint_id:
                return f.name
        return self.model.names[joint_id]

    def inertia_problems(self) -> list[str]:
        """Links whose URDF inertial data is not physically valid (mass <= 0, inertia not positive definite, or
        principal moments violating the triangle inequality)."""
        out = []
        for i in range(1, self.model.njoints):
            inertia = self.model.inertias[i]
            name = f'link {self.link_of_joint(i)} (joint {self.model.names[i]})'
            if inertia.mass <= 0:
                out.append(f'{name}: mass {inertia.mass:g} kg')
                continue
            ev = np.linalg.eigvalsh(inertia.inertia)
            if ev.min() <= 0:
                out.append(f'{name}: rotational inertia not positive definite (eigenvalues {np.round(ev, 6)})')
            elif ev[0] + ev[1] < ev[2] * (1 - 1e-9):
                out.append(f'{name}: principal moments {np.round(ev, 6)} violate the triangle inequality')
        return out


@dataclass
class Candidate:
    key: str
    name: str                 # in a robotics engineer's words
    family: str               # candidates of one family exclude each other (shared vs per joint)
    columns: np.ndarray       # (N * n, k)
    labels: list              # parameter names, one per column


def candidates(sig: ArmSignals, tau_model, Y_base) -> list[Candidate]:
    N, n = sig.q.shape
    names = sig.names
    out = []

    def per_joint(values):                       # (N, n) -> (N*n, n), column j only on joint j's rows
        cols = np.zeros((N, n, n))
        for j in range(n):
            cols[:, j, j] = values[:, j]
        return cols.reshape(N * n, n)

    smooth_sign = np.tanh(sig.qd / COULOMB_SMOOTHING_RAD_S)
    out.append(Candidate('viscous_shared', 'joint viscous friction (one coefficient for all joints)', 'viscous',
                         sig.qd.reshape(-1, 1), ['b_viscous_nms_per_rad']))
    out.append(Candidate('viscous', 'joint viscous friction (per joint)', 'viscous', per_joint(sig.qd),
                         [f'b_viscous_{j}_nms_per_rad' for j in names]))
    out.append(Candidate('coulomb_shared', 'joint Coulomb friction (one value for all joints)', 'coulomb',
                         smooth_sign.reshape(-1, 1), ['f_coulomb_nm']))
    out.append(Candidate('coulomb', 'joint Coulomb friction (per joint)', 'coulomb', per_joint(smooth_sign),
                         [f'f_coulomb_{j}_nm' for j in names]))
    out.append(Candidate('offset', 'torque sensor offset (per joint)', 'offset', per_joint(np.ones((N, n))),
                         [f'offset_{j}_nm' for j in names]))
    out.append(Candidate('gain', 'torque sensor gain error (per joint)', 'gain', per_joint(tau_model),
                         [f'gain_error_{j}' for j in names]))
    dtau = np.gradient(tau_model, sig.dt, axis=0)
    out.append(Candidate('delay', 'delay between torque sensors and encoders', 'delay', -dtau.reshape(-1, 1),
                         ['delay_s']))
    if Y_base is not None and Y_base.shape[1]:
        out.append(Candidate('inertial', "errors in the URDF's inertial parameters (masses, centres of mass, "
                             'inertias; base parameters)', 'inertial', Y_base,
                             [f'base_parameter_{i}' for i in range(Y_base.shape[1])]))
    return out


def base_columns(Y, tol=1e-8, max_rows=4000, seed=0):
    """Indices of a maximal independent set of regressor columns (the base parameters) by pivoted QR."""
    from scipy.linalg import qr
    rows = Y.reshape(-1, Y.shape[-1])
    if len(rows) > max_rows:
        rows = rows[np.random.default_rng(seed).choice(len(rows), max_rows, replace=False)]
    scale = np.linalg.norm(rows, axis=0)
    keep = scale > 1e-12 * max(scale.max(), 1e-300)
    idx = np.flatnonzero(keep)
    _, R, piv = qr(rows[:, idx] / scale[idx], mode='economic', pivoting=True)
    d = np.abs(np.diag(R))
    rank = int(np.sum(d > tol * d[0]))
    return np.sort(idx[piv[:rank]])


def torque_noise_rms(tau, window_samples, order=3):
    """RMS of the white measurement noise in the torques: tau minus its Savitzky-Golay smoothing, divided by
    sqrt(1 - c0) where c0 is the smoother's central weight (the share of the noise the smoothing keeps)."""
    from scipy.signal import savgol_coeffs
    w = window_samples if window_samples % 2 else window_samples + 1
    c0 = float(savgol_coeffs(w, order)[w // 2])
    high = tau - savgol_filter(tau, w, order, axis=0, mode='interp')
    return _rms(high) / math.sqrt(max(1.0 - c0, 1e-6))


def _rms(r):
    return float(np.sqrt(np.mean(r ** 2)))


def _errors(r_fit, r_val, names):
    return {'torque_rms_nm': _rms(r_val), 'per_joint_nm': {j: _rms(r_val[:, i]) for i, j in enumerate(names)},
            'fitted_part': {'torque_rms_nm': _rms(r_fit),
                            'per_joint_nm': {j: _rms(r_fit[:, i]) for i, j in enumerate(names)}}}


def diagnose_arm(sig: ArmSignals, arm: PinocchioArm, validation_fraction=0.3, min_gain=0.02, noise_margin=1.2,
                 progress=None) -> dict:
    """Forward selection of effects on the validation error; returns the report fields (see the module doc)."""
    t0 = time.monotonic()
    N, n = sig.q.shape
    if not 0.05 <= validation_fraction <= 0.8:
        raise ArmDiagnosisError(f'validation fraction {validation_fraction} outside 0.05-0.8')
    n_val = int(round(validation_fraction * N))
    if n_val < 50 or N - n_val < 100:
        raise ArmDiagnosisError(f'the window has {N} usable samples: too short to fit and validate (need at least '
                                f'100 to fit and 50 to validate; {sig.dt * N:.2f} s at {1 / sig.dt:.0f} Hz)')
    spread = np.ptp(sig.tau, axis=0)
    flat = [sig.names[j] for j in range(n) if spread[j] < 1e-9]
    if len(flat) == n:
        raise ArmDiagnosisError('every joint effort is constant (all zero?): the recording has no torque '
                                'information to diagnose')
    tau_model = arm.inverse_dynamics(sig.q, sig.qd, sig.qdd)
    residual = sig.tau - tau_model
    if progress:
        progress({'stage': 'regressor', 'fraction': 0.2})
    Y = arm.torque_regressor(sig.q, sig.qd, sig.qdd)
    base = base_columns(Y)
    Y_base = Y[:, :, base].reshape(N * n, len(base))
    cands = candidates(sig, tau_model, Y_base)
    fit_rows = np.zeros((N, n), bool)
    fit_rows[:N - n_val] = True
    fit_rows = fit_rows.reshape(-1)
    # joints with constant effort (no sensor) are left out of fitting and scoring
    use = np.tile(spread >= 1e-9, N)
    r = residual.reshape(-1)

    def fit(blocks):
        if not blocks:
            return np.zeros(0), np.zeros_like(r)
        A = np.hstack([c.columns for c in blocks])
        m = fit_rows & use
        scale = np.linalg.norm(A[m], axis=0)
        scale[scale == 0] = 1.0
        x, *_ = np.linalg.lstsq(A[m] / scale, r[m], rcond=1e-10)
        x = x / scale
        return x, A @ x

    def split(pred):
        res = (r - pred) * use
        res = res.reshape(N, n)
        return res[:N - n_val], res[N - n_val:]

    def val_rms(pred):
        return _rms(split(pred)[1][:, spread >= 1e-9])

    active = spread >= 1e-9
    noise = torque_noise_rms(sig.tau[:, active], sig.window_samples)
    selected, rounds = [], []
    current = val_rms(np.zeros_like(r))
    before = _errors(*split(np.zeros_like(r)), sig.names)
    effects = []
    while True:
        options = [c for c in cands if c.family not in {s.family for s in selected}]
        if not options:
            break
        scores = []
        for c in options:
            _, pred = fit(selected + [c])
            scores.append((val_rms(pred), c))
        scores.sort(key=lambda s: s[0])
        rounds.append({'validation_rms_before_nm': current,
                       'candidates': {c.key: s for s, c in scores}})
        best_rms, best = scores[0]
        if best_rms > (1.0 - min_gain) * current or current <= noise_margin * noise:
            break
        err_before = _errors(*split(fit(selected)[1]), sig.names)
        selected.append(best)
        x, pred = fit(selected)
        err_after = _errors(*split(pred), sig.names)
        effects.append({'name': best.name, 'key': best.key,
                        'evidence': f'validation torque RMS {current:.4f} -> {best_rms:.4f} N m '
                                    f'({100 * (1 - best_rms / current):.1f} % lower on data never fitted)',
                        'error_before': err_before, 'error_after': err_after})
        current = best_rms
        if progress:
            progress({'stage': 'diagnose', 'effect': best.key, 'validation_rms_nm': best_rms})
    x, pred = fit(selected)
    k = 0
    contributions = {}
    for eff, c in zip(effects, selected):
        vals = x[k:k + len(c.labels)]
        k += len(c.labels)
        contributions[c.key] = (c.columns @ vals).reshape(N, n)
        eff['parameters'] = {lab: float(v) for lab, v in zip(c.labels, vals)} if c.key != 'inertial' else {
            'base_parameters_fitted': len(c.labels)}
    after = _errors(*split(pred), sig.names)
    inertial = any(c.key == 'inertial' for c in selected)
    return {'effects_added': effects, 'error_before': before, 'error_after': after, 'rounds': rounds,
            'base_parameters': int(len(base)), 'inertial_data_wrong': inertial, 'torque_noise_rms_nm': noise,
            'samples': {'fitted': int(N - n_val), 'validation': int(n_val), 'dt_s': sig.dt,
                        'savgol_window_samples': sig.window_samples},
            'constant_effort_joints': flat, 'wall_time_s': time.monotonic() - t0,
            '_prediction': pred.reshape(N, n), '_residual': residual, '_contributions': contributions}
