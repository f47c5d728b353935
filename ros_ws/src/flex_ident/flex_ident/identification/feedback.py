"""The stabilizing feedback of the measured-torque simulation (paper Sec. IV-C), with gains from a finite-horizon LQR.

Measured torques alone do not keep a simulated arm on the measured path (model and sensor errors integrate), so the
simulation is driven by the measured torques plus feedback on the measured arm angles:

    tau = tau_meas + Kp (theta_meas - theta) + Kd (theta_meas_rate - theta_rate).

The paper evaluates a proportional term at the sample (explicit). Here the feedback is a generalized force of the
variational step, evaluated at the step midpoint like the springs (see mechanics.variational_integrator), with a rate
term towards the measured angles' finite-difference rate. That keeps the closed loop passive, hence stable for any
positive gains and any parameter value the optimizer tries, which the explicit proportional form is not: with
stiff enough gains to survive a poor initial guess, the angle-only part of a full-state LQR gain destabilizes light
wrist joints.

Gains: finite-horizon discrete LQR (backward Riccati recursion) on the arm linearized at the initial pose, error
state (e, e_rate) with M_aa e_acc = u - C e_rate (M_aa: the model's mass matrix on the arm joints, the loop's inertia
included; C: declared joint damping), zero-order-hold discretized at the sample period. Bryson's rule sets the
weights: angle errors of ``angle_tolerance_rad`` cost as much as feedback torques of ``torque_tolerance_nm``. Over a
recording-long horizon the gain is its stationary value; it is computed once and held fixed while the parameters
are identified, so the cost is one smooth function of the parameters.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ..mechanics.tree_kinematics import generalized_forces, lagrangian_derivatives
from ..mechanics.variational_integrator import TrackingFeedback


@dataclass(frozen=True)
class FeedbackWeights:
    """Bryson's rule: Q = I / angle_tolerance^2 (+ I / rate_tolerance^2), R = I / torque_tolerance^2."""
    angle_tolerance_rad: float = 0.005
    torque_tolerance_nm: float = 1.0
    rate_tolerance_rad_s: float = np.inf


def riccati_gains(A, B, Q, R, terminal=None) -> np.ndarray:
    """Finite-horizon discrete LQR gains K_k (len(A), nu, nx) for x_{k+1} = A_k x_k + B_k u_k, u_k = -K_k x_k:

    K_k = (R + B_k^T X_{k+1} B_k)^{-1} B_k^T X_{k+1} A_k,  X_k = Q + A_k^T X_{k+1} (A_k - B_k K_k),  X_T = terminal.
    """
    steps, nx, _ = A.shape
    nu = B.shape[2]
    X = np.array(Q if terminal is None else terminal, dtype=float)
    K = np.empty((steps, nu, nx))
    for k in range(steps - 1, -1, -1):
        Ak, Bk = A[k], B[k]
        XB = X @ Bk
        K[k] = np.linalg.solve(R + Bk.T @ XB, XB.T @ Ak)
        X = Q + Ak.T @ X @ (Ak - Bk @ K[k])
        X = 0.5 * (X + X.T)
    return K


def arm_error_dynamics(model, coef, q, dt):
    """ZOH-discretized (A, B) of the arm tracking error e = theta_meas - theta: M_aa e_acc = u - C e_rate."""
    n = model.n
    nc = len(coef)
    nu = len(model.input_coords)
    idx = model.measured_coords
    na = len(idx)
    Lvv = np.zeros((n, n))
    km = model.kernel()
    lagrangian_derivatives(km, np.asarray(q, float), np.zeros(n), np.asarray(coef, float), True, np.zeros(n),
                           np.zeros(n), np.zeros((n, n)), np.zeros((n, n)), Lvv, np.zeros((n, nc)))
    dF_dv = np.zeros((n, n))
    generalized_forces(km, np.asarray(q, float), np.zeros(n), np.zeros(nu), np.asarray(coef, float), np.zeros(n),
                       np.zeros((n, n)), dF_dv, np.zeros((n, nu)), np.zeros((n, nc)))
    M = Lvv[np.ix_(idx, idx)]
    C = -dF_dv[np.ix_(idx, idx)]
    Minv = np.linalg.inv(M)
    Ac = np.zeros((2 * na, 2 * na))
    Ac[:na, na:] = np.eye(na)
    Ac[na:, na:] = -Minv @ C
    Bc = np.zeros((2 * na, na))
    Bc[na:] = Minv
    aug = np.zeros((3 * na, 3 * na))
    aug[:2 * na, :2 * na] = Ac
    aug[:2 * na, 2 * na:] = Bc
    E = expm(aug * dt)
    return E[:2 * na, :2 * na], E[:2 * na, 2 * na:]


def lqr_tracking_feedback(model, coef, q, dt, weights: FeedbackWeights = FeedbackWeights(),
                          horizon_steps: int = 2000) -> TrackingFeedback:
    """Kp, Kd (na, na) from the finite-horizon LQR on the arm error dynamics at configuration q (the first gain of
    the horizon: its stationary value for a recording-long horizon)."""
    A, B = arm_error_dynamics(model, coef, q, dt)
    na = len(model.measured_coords)
    Q = np.zeros((2 * na, 2 * na))
    Q[:na, :na] = np.eye(na) / weights.angle_tolerance_rad ** 2
    if np.isfinite(weights.rate_tolerance_rad_s):
        Q[na:, na:] = np.eye(na) / weights.rate_tolerance_rad_s ** 2
    R = np.eye(na) / weights.torque_tolerance_nm ** 2
    steps = max(2, int(horizon_steps))
    K = riccati_gains(np.repeat(A[None], steps, axis=0), np.repeat(B[None], steps, axis=0), Q, R)[0]
    return TrackingFeedback(Kp=np.ascontiguousarray(K[:, :na]), Kd=np.ascontiguousarray(K[:, na:]))
