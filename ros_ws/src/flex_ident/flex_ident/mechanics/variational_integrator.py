"""Midpoint variational integrator with holonomic constraints (paper Sec. II-B, Eqs. 2-5 and 13).

Discrete Lagrangian L_d(q_k, q_{k+1}) = dt L((q_k + q_{k+1})/2, (q_{k+1} - q_k)/dt); discrete forces split
symmetrically, f_k^- = f_k^+ = (dt/2) F(q_mid, v, u_k) (second order with forcing). Momentum form (Eq. 4-5):

    p_k + D1 L_d(q_k, q_{k+1}) + f_k^- - Dh(q_k)^T lambda_k = 0,    h(q_{k+1}) = 0,
    p_{k+1} = D2 L_d(q_k, q_{k+1}) + f_k^+,

solved for (q_{k+1}, lambda_k) by Newton with the exact Jacobian [[M2, -Dh(q_k)^T], [Dh(q_{k+1}), 0]],
M2 = D2 D1 L_d + d f_k^- / d q_{k+1}. With D1 L_d = dt/2 L_q - L_v and D2 L_d = dt/2 L_q + L_v at the midpoint,

    D1D1 L_d = dt/4 Lqq - (Lqv + Lqv^T)/2 + Lvv/dt      D2D1 L_d = dt/4 Lqq + (Lqv - Lqv^T)/2 - Lvv/dt
    D1D2 L_d = dt/4 Lqq - (Lqv - Lqv^T)/2 - Lvv/dt      D2D2 L_d = dt/4 Lqq + (Lqv + Lqv^T)/2 + Lvv/dt

where DaDb L_d means d(Db L_d)/d(slot a). Inputs u_k may carry the paper's stabilizing feedback
u_k = tau_k + G_k (theta_meas,k - S q_k) (Sec. IV-C).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .tree_kinematics import generalized_forces, lagrangian_derivatives, weld_constraints

NEWTON_MAX_ITERATIONS = 30
DEL_TOLERANCE = 1e-11          # on the discrete Euler-Lagrange residual (momentum units)
CONSTRAINT_TOLERANCE = 1e-12   # on h(q_{k+1}) [m, rad]


class SimulationError(RuntimeError):
    """The implicit step did not converge (the model left its valid region or the input made no sense)."""


@njit(cache=True)
def step_derivatives(km, coef, dt, qk, qn, u, second, out_Lq, out_Lv, Lqq, Lqv, Lvv, dLq_dc,
                     F, dF_dq, dF_dv, dF_du, dF_dc):
    """Lagrangian and force terms at the midpoint of (qk, qn): fills the given arrays."""
    n = qk.shape[0]
    qm = np.empty(n)
    v = np.empty(n)
    for i in range(n):
        qm[i] = 0.5 * (qk[i] + qn[i])
        v[i] = (qn[i] - qk[i]) / dt
    lagrangian_derivatives(km, qm, v, coef, second, out_Lq, out_Lv, Lqq, Lqv, Lvv, dLq_dc)
    generalized_forces(km, qm, v, u, coef, F, dF_dq, dF_dv, dF_du, dF_dc)


@njit(cache=True)
def newton_step(km, coef, dt, qk, pk, u, Dhk, q_guess, lam_guess, qn_out, lam_out, pn_out, max_iterations):
    """One step of the forced constrained DEL. Returns (iterations, converged, constraint residual)."""
    n = qk.shape[0]
    m = Dhk.shape[0]
    nu = u.shape[0]
    nc = coef.shape[0]
    Lq = np.empty(n)
    Lv = np.empty(n)
    Lqq = np.empty((n, n))
    Lqv = np.empty((n, n))
    Lvv = np.empty((n, n))
    dLq_dc = np.empty((n, nc))
    F = np.empty(n)
    dF_dq = np.empty((n, n))
    dF_dv = np.empty((n, n))
    dF_du = np.empty((n, nu))
    dF_dc = np.empty((n, nc))
    h = np.empty(m)
    Dhn = np.empty((m, n))
    Hdummy = np.empty((1, 1))
    K = np.zeros((n + m, n + m))
    rhs = np.empty(n + m)
    q = q_guess.copy()
    lam = lam_guess.copy()
    converged = False
    it = 0
    hmax = 0.0
    scale = 1.0
    for i in range(n):
        scale = max(scale, abs(pk[i]))
    while True:
        step_derivatives(km, coef, dt, qk, q, u, True, Lq, Lv, Lqq, Lqv, Lvv, dLq_dc, F, dF_dq, dF_dv, dF_du, dF_dc)
        weld_constraints(km, q, lam, False, h, Dhn, Hdummy)
        rmax = 0.0
        for i in range(n):
            r = pk[i] + 0.5 * dt * Lq[i] - Lv[i] + 0.5 * dt * F[i]
            for c in range(m):
                r -= Dhk[c, i] * lam[c]
            rhs[i] = -r
            rmax = max(rmax, abs(r))
        hmax = 0.0
        for c in range(m):
            rhs[n + c] = -h[c]
            hmax = max(hmax, abs(h[c]))
        if rmax <= DEL_TOLERANCE * scale and hmax <= CONSTRAINT_TOLERANCE:
            converged = True
            break
        if it >= max_iterations:
            break
        for i in range(n):
            for j in range(n):
                K[i, j] = (0.25 * dt * Lqq[i, j] + 0.5 * (Lqv[i, j] - Lqv[j, i]) - Lvv[i, j] / dt
                           + 0.25 * dt * dF_dq[i, j] + 0.5 * dF_dv[i, j])
            for c in range(m):
                K[i, n + c] = -Dhk[c, i]
                K[n + c, i] = Dhn[c, i]
        delta = np.linalg.solve(K, rhs)
        for i in range(n):
            q[i] += delta[i]
        for c in range(m):
            lam[c] += delta[n + c]
        it += 1
    for i in range(n):
        qn_out[i] = q[i]
        pn_out[i] = 0.5 * dt * Lq[i] + Lv[i] + 0.5 * dt * F[i]
    for c in range(m):
        lam_out[c] = lam[c]
    return it, converged, hmax


@njit(cache=True)
def simulate_kernel(km, coef, dt, q0, p0, tau, theta_ref, gains, measured, Q, P, LAM, U, ITER):
    """Integrate T-1 steps from (q0, p0). Input of step k: u_k = tau[k] + G_k (theta_ref[k] - q_k[measured]),
    G_k = gains[min(k, len(gains) - 1)]. Returns the number of steps completed (T-1 on success)."""
    T = Q.shape[0]
    n = q0.shape[0]
    m = LAM.shape[1]
    nu = tau.shape[1]
    na = measured.shape[0]
    Q[0] = q0
    P[0] = p0
    h = np.empty(m)
    Dhk = np.empty((m, n))
    Hd = np.empty((1, 1))
    weld_constraints(km, q0, np.zeros(m), False, h, Dhk, Hd)
    lam_guess = np.zeros(m)
    q_guess = np.empty(n)
    u = np.empty(nu)
    ng = gains.shape[0]
    for k in range(T - 1):
        G = gains[min(k, ng - 1)]
        for a in range(nu):
            s = tau[k, a]
            for b in range(na):
                s += G[a, b] * (theta_ref[k, b] - Q[k, measured[b]])
            u[a] = s
        U[k] = u
        if k == 0:
            q_guess[:] = Q[0]
        else:
            for i in range(n):
                q_guess[i] = 2.0 * Q[k, i] - Q[k - 1, i]
        it, ok, hmax = newton_step(km, coef, dt, Q[k], P[k], u, Dhk, q_guess, lam_guess, Q[k + 1], LAM[k],
                                   P[k + 1], NEWTON_MAX_ITERATIONS)
        ITER[k] = it
        if not ok:
            return k
        lam_guess[:] = LAM[k]
        weld_constraints(km, Q[k + 1], lam_guess, False, h, Dhk, Hd)
    return T - 1


@dataclass
class Trajectory:
    """A simulated trajectory on the time grid t_k = k dt, k = 0..T-1.

    q, p: (T, n) configurations and discrete momenta; lam: (T-1, m) multipliers of step k; u: (T-1, nu) the inputs
    applied over [t_k, t_{k+1}] (feedback included); newton_iterations: (T-1,).
    """
    dt: float
    q: np.ndarray
    p: np.ndarray
    lam: np.ndarray
    u: np.ndarray
    newton_iterations: np.ndarray
    coef: np.ndarray


def simulate(model, coef, dt: float, q0, p0, tau, theta_ref=None, gains=None) -> Trajectory:
    """Simulate ``len(tau)`` steps driven by inputs ``tau`` (T-1, nu), optionally with proportional feedback
    u_k = tau_k + G_k (theta_ref_k - q_k[measured]) (gains: (nu, na), (T-1, nu, na) or None)."""
    km = model.kernel()
    tau = np.ascontiguousarray(np.atleast_2d(tau), dtype=float)
    steps = tau.shape[0]
    T = steps + 1
    n, m = model.n, model.n_constraints
    na = len(model.measured_coords)
    nu = len(model.input_coords)
    if tau.shape[1] != nu:
        raise ValueError(f'tau has {tau.shape[1]} columns, the model has {nu} inputs')
    if theta_ref is None:
        theta_ref = np.zeros((T, na))
    if gains is None:
        gains = np.zeros((1, nu, na))
    gains = np.asarray(gains, dtype=float)
    if gains.ndim == 2:
        gains = gains[None]
    Q = np.empty((T, n))
    P = np.empty((T, n))
    LAM = np.zeros((steps, m))
    U = np.empty((steps, nu))
    ITER = np.zeros(steps, dtype=np.int64)
    coef = np.ascontiguousarray(coef, dtype=float)
    done = simulate_kernel(km, coef, float(dt), np.ascontiguousarray(q0, dtype=float),
                           np.ascontiguousarray(p0, dtype=float), tau, np.ascontiguousarray(theta_ref, dtype=float),
                           np.ascontiguousarray(gains), model.measured_coords, Q, P, LAM, U, ITER)
    if done < steps:
        raise SimulationError(f'the variational integrator step did not converge at t = {done * dt:.3f} s '
                              f'(step {done} of {steps}); the simulated motion left the model\'s valid region')
    return Trajectory(dt=float(dt), q=Q, p=P, lam=LAM, u=U, newton_iterations=ITER, coef=coef.copy())


def continuous_momentum(model, coef, q, v) -> np.ndarray:
    """dL/dqdot at (q, v): the momentum that starts a trajectory with velocity v (p_0 for a moving start)."""
    from .tree_kinematics import lagrangian_derivatives as ld
    n = model.n
    nc = len(coef)
    Lq, Lv = np.zeros(n), np.zeros(n)
    ld(model.kernel(), np.asarray(q, float), np.asarray(v, float), np.asarray(coef, float), False, Lq, Lv,
       np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((n, nc)))
    return Lv


def rest_momentum(model, coef, dt, q0, u0) -> np.ndarray:
    """p_0 = D2 L_d(q0, q0) + f^+ for a system at rest at q0 under input u0 (then it stays at rest if q0 is an
    equilibrium under u0): -dt/2 grad V(q0) + dt/2 F(q0, 0, u0)."""
    n = model.n
    nc = len(coef)
    nu = len(model.input_coords)
    Lq, Lv = np.zeros(n), np.zeros(n)
    F = np.zeros(n)
    km = model.kernel()
    q0 = np.asarray(q0, float)
    coef = np.asarray(coef, float)
    lagrangian_derivatives(km, q0, np.zeros(n), coef, False, Lq, Lv, np.zeros((1, 1)), np.zeros((1, 1)),
                           np.zeros((1, 1)), np.zeros((n, nc)))
    generalized_forces(km, q0, np.zeros(n), np.asarray(u0, float).reshape(nu), coef, F, np.zeros((n, n)),
                       np.zeros((n, n)), np.zeros((n, nu)), np.zeros((n, nc)))
    return 0.5 * dt * Lq + Lv + 0.5 * dt * F


def energy(model, coef, q, v) -> tuple[float, float]:
    """(kinetic, potential) energy [J] at configuration q and velocity v."""
    n = model.n
    nc = len(coef)
    return lagrangian_derivatives(model.kernel(), np.asarray(q, float), np.asarray(v, float), np.asarray(coef, float),
                                  False, np.zeros(n), np.zeros(n), np.zeros((1, 1)), np.zeros((1, 1)),
                                  np.zeros((1, 1)), np.zeros((n, nc)))


def constraint_residual(model, q) -> np.ndarray:
    """h(q): the weld constraints (6 per weld: position [m], then vee(skew(R_T^T R)))."""
    m = model.n_constraints
    h = np.zeros(m)
    weld_constraints(model.kernel(), np.asarray(q, float), np.zeros(m), False, h, np.zeros((m, model.n)),
                     np.zeros((1, 1)))
    return h


def constraint_jacobian(model, q) -> np.ndarray:
    m = model.n_constraints
    Dh = np.zeros((m, model.n))
    weld_constraints(model.kernel(), np.asarray(q, float), np.zeros(m), False, np.zeros(m), Dh, np.zeros((1, 1)))
    return Dh
