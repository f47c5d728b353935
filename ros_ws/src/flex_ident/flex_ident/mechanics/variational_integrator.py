"""Midpoint variational integrator with holonomic constraints (paper Sec. II-B, Eqs. 2-5 and 13).

Discrete Lagrangian L_d(q_k, q_{k+1}) = dt L((q_k + q_{k+1})/2, (q_{k+1} - q_k)/dt); discrete forces split
symmetrically, f_k^- = f_k^+ = (dt/2) F(q_mid, v, u_k) (second order with forcing). Momentum form (Eq. 4-5):

    p_k + D1 L_d(q_k, q_{k+1}) + f_k^- - Dh(q_k)^T lambda_k = 0,    h(q_{k+1}) = 0,
    p_{k+1} = D2 L_d(q_k, q_{k+1}) + f_k^+,

solved for (q_{k+1}, lambda_k) by Newton with the exact Jacobian [[M2, -Dh(q_k)^T], [Dh(q_{k+1}), 0]],
M2 = D2 D1 L_d + d f_k^- / d q_{k+1}. With D1 L_d = dt/2 L_q - L_v and D2 L_d = dt/2 L_q + L_v at the midpoint,

    D1D1 L_d = dt/4 Lqq - (Lqv + Lqv^T)/2 + Lvv/dt      D2D1 L_d = dt/4 Lqq + (Lqv - Lqv^T)/2 - Lvv/dt
    D1D2 L_d = dt/4 Lqq - (Lqv - Lqv^T)/2 - Lvv/dt      D2D2 L_d = dt/4 Lqq + (Lqv + Lqv^T)/2 + Lvv/dt

where DaDb L_d means d(Db L_d)/d(slot a). The step input carries the measured torques and, for the stabilizing
feedback on the measured arm angles (paper Sec. IV-C), their reference: the feedback torque is evaluated at the step's
midpoint like every other force (:class:`TrackingFeedback`), which keeps it unconditionally stable.
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
def simulate_kernel(km, coef, h, q0, p0, U, Q, P, LAM, ITER):
    """Integrate len(U) VI steps of size h from (q0, p0) with step inputs U (steps, nw).

    Q, P: (steps + 1, n); LAM: (steps, m). Returns the number of steps completed.
    """
    steps = U.shape[0]
    n = q0.shape[0]
    m = LAM.shape[1]
    Q[0] = q0
    P[0] = p0
    h_ = np.empty(m)
    Dhk = np.empty((m, n))
    Hd = np.empty((1, 1))
    weld_constraints(km, q0, np.zeros(m), False, h_, Dhk, Hd)
    lam_guess = np.zeros(m)
    q_guess = np.empty(n)
    for j in range(steps):
        if j == 0:
            q_guess[:] = Q[0]
        elif j == 1:
            for i in range(n):
                q_guess[i] = 2.0 * Q[j, i] - Q[j - 1, i]
        else:                                   # quadratic extrapolation: usually one Newton step suffices
            for i in range(n):
                q_guess[i] = 3.0 * Q[j, i] - 3.0 * Q[j - 1, i] + Q[j - 2, i]
        it, ok, hmax = newton_step(km, coef, h, Q[j], P[j], U[j], Dhk, q_guess, lam_guess, Q[j + 1], LAM[j],
                                   P[j + 1], NEWTON_MAX_ITERATIONS)
        ITER[j] = it
        if not ok:
            return j
        lam_guess[:] = LAM[j]
        weld_constraints(km, Q[j + 1], lam_guess, False, h_, Dhk, Hd)
    return steps


@dataclass(frozen=True)
class TrackingFeedback:
    """Feedback on the measured arm angles acting inside the step (at the midpoint, hence implicit):
    tau_fb = Kp (theta_meas(t_mid) - q_arm,mid) + Kd (theta_meas_rate - qdot_arm), Kp, Kd (na, na)."""
    Kp: np.ndarray
    Kd: np.ndarray


def step_inputs(model, tau, theta_ref=None, dt=None, substeps: int = 1):
    """Per-VI-step input vectors (steps*substeps, nu + 2 na): the torque of the sample interval, then the reference
    angles at the VI step's midpoint (linear between samples) and the reference rate (theta_{k+1} - theta_k)/dt."""
    tau = np.atleast_2d(np.asarray(tau, dtype=float))
    steps, nu = tau.shape
    na = len(model.measured_coords)
    W = np.zeros((steps * substeps, nu + 2 * na))
    W[:, :nu] = np.repeat(tau, substeps, axis=0)
    if theta_ref is not None:
        th = np.asarray(theta_ref, dtype=float)
        rate = (th[1:steps + 1] - th[:steps]) / dt
        for sub in range(substeps):
            frac = (sub + 0.5) / substeps
            W[sub::substeps, nu:nu + na] = th[:steps] + frac * (th[1:steps + 1] - th[:steps])
            W[sub::substeps, nu + na:] = rate
    return W


def feedback_kernel(model, feedback: TrackingFeedback | None):
    km = model.kernel()
    if feedback is None:
        return km
    return km._replace(fb_Kp=np.ascontiguousarray(feedback.Kp, dtype=float),
                       fb_Kd=np.ascontiguousarray(feedback.Kd, dtype=float))


@dataclass
class Trajectory:
    """A simulated trajectory on the sample grid t_k = k dt, k = 0..T-1 (each interval ``substeps`` VI steps).

    q_fine, p_fine: ((T-1) substeps + 1, n) configurations and discrete momenta on the VI grid (step dt/substeps);
    lam_fine: ((T-1) substeps, m) multipliers; u_fine: the step inputs (torque, feedback reference);
    newton_iterations: per VI step. ``q``, ``p`` are the states at the samples; ``feedback_torque`` (T-1, na) the
    tracking feedback's torque at each interval's first VI step.
    """
    dt: float
    substeps: int
    q_fine: np.ndarray
    p_fine: np.ndarray
    lam_fine: np.ndarray
    u_fine: np.ndarray
    newton_iterations: np.ndarray
    coef: np.ndarray
    feedback: TrackingFeedback | None = None

    @property
    def q(self) -> np.ndarray:
        return self.q_fine[::self.substeps]

    @property
    def p(self) -> np.ndarray:
        return self.p_fine[::self.substeps]

    @property
    def x(self) -> np.ndarray:
        """(T, 2n) discrete states x_k = (q_k, p_k)."""
        return np.hstack([self.q, self.p])


def simulate(model, coef, dt: float, q0, p0, tau, theta_ref=None, feedback: TrackingFeedback | None = None,
             substeps: int = 1) -> Trajectory:
    """Simulate ``len(tau)`` sample intervals of ``dt`` driven by torques ``tau`` (T-1, nu) (held over each
    interval), each as ``substeps`` VI steps, optionally with the tracking feedback towards ``theta_ref`` (T, na).

    Raises :class:`SimulationError` if a step does not converge."""
    tau = np.ascontiguousarray(np.atleast_2d(tau), dtype=float)
    steps = tau.shape[0]
    n, m = model.n, model.n_constraints
    nu = len(model.input_coords)
    if tau.shape[1] != nu:
        raise ValueError(f'tau has {tau.shape[1]} columns, the model has {nu} inputs')
    substeps = int(substeps)
    U = step_inputs(model, tau, theta_ref if feedback is not None else None, dt, substeps)
    nf = steps * substeps
    Q = np.empty((nf + 1, n))
    P = np.empty((nf + 1, n))
    LAM = np.zeros((nf, m))
    ITER = np.zeros(nf, dtype=np.int64)
    coef = np.ascontiguousarray(coef, dtype=float)
    done = simulate_kernel(feedback_kernel(model, feedback), coef, float(dt) / substeps,
                           np.ascontiguousarray(q0, dtype=float), np.ascontiguousarray(p0, dtype=float), U, Q, P, LAM,
                           ITER)
    if done < nf:
        raise SimulationError(f'the variational integrator step did not converge at t = {done * dt / substeps:.3f} s '
                              f'(step {done} of {nf}); the simulated motion left the model\'s valid region')
    return Trajectory(dt=float(dt), substeps=substeps, q_fine=Q, p_fine=P, lam_fine=LAM, u_fine=U,
                      newton_iterations=ITER, coef=coef.copy(), feedback=feedback)


def continuous_momentum(model, coef, q, v) -> np.ndarray:
    """dL/dqdot at (q, v): the momentum that starts a trajectory with velocity v (p_0 for a moving start)."""
    from .tree_kinematics import lagrangian_derivatives as ld
    n = model.n
    nc = len(coef)
    Lq, Lv = np.zeros(n), np.zeros(n)
    ld(model.kernel(), np.asarray(q, float), np.asarray(v, float), np.asarray(coef, float), False, Lq, Lv,
       np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((n, nc)))
    return Lv


def rest_momentum(model, coef, h, q0, tau0) -> np.ndarray:
    """p_0 = D2 L_d(q0, q0) + f^+ for a system at rest at q0 under torques tau0, VI step h (then it stays at rest
    if q0 is an equilibrium under tau0): -h/2 grad V(q0) + h/2 F(q0, 0, tau0). A tracking feedback referenced to
    the resting angles adds nothing."""
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
    generalized_forces(km, q0, np.zeros(n), np.asarray(tau0, float).reshape(nu), coef, F, np.zeros((n, n)),
                       np.zeros((n, n)), np.zeros((n, nu)), np.zeros((n, nc)))
    return 0.5 * h * Lq + Lv + 0.5 * h * F


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


def stable_substeps(model, coef, dt, q_eq, mu_eq, safety: float = 3.0, max_substeps: int = 8) -> int:
    """VI substeps per sample interval ``dt`` that keep the constrained midpoint rule linearly stable.

    The constraint force -Dh(q_k)^T lambda_k acts at the node q_k, so its curvature stiffness H = sum mu_i D2 h_i is
    integrated explicitly (like leapfrog) while springs and gravity are averaged over the midpoint: on the constraint
    manifold (basis Z), the step is stable iff every eigenvalue of (Z^T H Z, Z^T M Z) is below 4 / h^2. Light links
    under tension (the contract loop: 50 g cylinders, 1e-5 kg m^2 about their axis) can violate that at dt = 0.01 s,
    so the sample interval is split into the fewest substeps with ``safety`` margin on kappa_max.
    """
    from scipy.linalg import eigh, null_space
    m = model.n_constraints
    if m == 0:
        return 1
    n = model.n
    nc = len(coef)
    Lvv = np.zeros((n, n))
    lagrangian_derivatives(model.kernel(), np.asarray(q_eq, float), np.zeros(n), np.asarray(coef, float), True,
                           np.zeros(n), np.zeros(n), np.zeros((n, n)), np.zeros((n, n)), Lvv, np.zeros((n, nc)))
    h, Dh, H = np.zeros(m), np.zeros((m, n)), np.zeros((n, n))
    weld_constraints(model.kernel(), np.asarray(q_eq, float), np.asarray(mu_eq, float), True, h, Dh, H)
    Z = null_space(Dh)
    if Z.shape[1] == 0:
        return 1                     # no motion left on the constraint manifold
    kappa = float(np.max(eigh(Z.T @ H @ Z, Z.T @ Lvv @ Z, eigvals_only=True)))
    if kappa <= 0:
        return 1
    return int(min(max_substeps, max(1, np.ceil(dt * np.sqrt(safety * kappa) / 2.0))))


@njit(cache=True)
def _midpoint_energies(km, coef, Q, h, out):
    n = Q.shape[1]
    nc = coef.shape[0]
    Lq = np.empty(n)
    Lv = np.empty(n)
    d = np.empty((1, 1))
    dc = np.empty((n, nc))
    qm = np.empty(n)
    v = np.empty(n)
    for k in range(Q.shape[0] - 1):
        for i in range(n):
            qm[i] = 0.5 * (Q[k, i] + Q[k + 1, i])
            v[i] = (Q[k + 1, i] - Q[k, i]) / h
        T, V = lagrangian_derivatives(km, qm, v, coef, False, Lq, Lv, d, d, d, dc)
        out[k] = T + V


def midpoint_energies(model, coef, q_fine, h) -> np.ndarray:
    """Total energy T + V [J] at the midpoint of every VI step (velocity (q_{k+1} - q_k)/h)."""
    Q = np.ascontiguousarray(q_fine, dtype=float)
    out = np.empty(len(Q) - 1)
    _midpoint_energies(model.kernel(), np.ascontiguousarray(coef, dtype=float), Q, float(h), out)
    return out


def required_substeps(model, traj, safety: float = 1.5, worst_steps: int = 5, max_substeps: int = 8) -> int:
    """Substeps per sample that :func:`stable_substeps` asks for at the ``worst_steps`` VI steps of ``traj`` with the
    largest constraint forces (the weld curvature stiffness grows with the loop's tension during the motion)."""
    if model.n_constraints == 0 or traj.lam_fine.shape[0] == 0:
        return 1
    h = traj.dt / traj.substeps
    norms = np.linalg.norm(traj.lam_fine, axis=1)
    worst = np.argsort(norms)[-worst_steps:]
    return max(stable_substeps(model, traj.coef, traj.dt, traj.q_fine[j], traj.lam_fine[j] / h, safety, max_substeps)
               for j in worst)
