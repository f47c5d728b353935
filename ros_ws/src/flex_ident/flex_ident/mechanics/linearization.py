"""Linearization of the one-step map x_{k+1} = f(x_k, u_k; c) along a trajectory (paper Eqs. 6-8, Sec. IV-D).

Implicit function theorem on the step equations (VI_ADJOINT_MATH.md): with, at the midpoint of (q_k, q_{k+1}),

    M2 = D2D1 L_d + df^-/dq_{k+1},    M1 = D1D1 L_d + df^-/dq_k - sum_i lambda_k,i D2 h_i(q_k),
    N1 = D1D2 L_d + df^+/dq_k,        N2 = D2D2 L_d + df^+/dq_{k+1},

the bordered system [[M2, -Dh(q_k)^T], [Dh(q_{k+1}), 0]] [dq_{k+1}; dlambda] = [rhs; 0] with
rhs = -(M1 dq_k + dp_k + df^-/du du + (dD1L_d/dc + df^-/dc) dc) gives dq_{k+1}, then

    dp_{k+1} = N1 dq_k + N2 dq_{k+1} + df^+/du du + (dD2L_d/dc + df^+/dc) dc.

Coefficient derivatives (paper Sec. IV-D): for a spring V = k (q_i - r)^2 / 2, dD1L_d/dk = dD2L_d/dk =
-(dt/2) (q_mid,i - r) e_i; damping and the other terms contribute through df/dc. When a sample interval is made of
several VI substeps their maps are composed. The tracking feedback on the measured angles is a generalized force of
the step (see variational_integrator.TrackingFeedback), so A_k is the closed-loop map (gains held fixed).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .tree_kinematics import weld_constraints
from .variational_integrator import step_derivatives


@njit(cache=True)
def step_matrices(km, coef, dt, qk, qn, lam, u):
    """Matrices of one VI step's linearization: K (bordered, n+m square), M1, N1, N2 (n, n), Fu = d f/du
    (n, nw) and Fc = dD1L_d/dc + df/dc = dD2L_d/dc + df^+/dc (n, ncoef) (equal for the symmetric split)."""
    n = qk.shape[0]
    m = lam.shape[0]
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
    step_derivatives(km, coef, dt, qk, qn, u, True, Lq, Lv, Lqq, Lqv, Lvv, dLq_dc, F, dF_dq, dF_dv, dF_du, dF_dc)
    h = np.empty(m)
    Dhk = np.empty((m, n))
    Dhn = np.empty((m, n))
    Hk = np.empty((n, n))
    Hd = np.empty((1, 1))
    weld_constraints(km, qk, lam, True, h, Dhk, Hk)
    weld_constraints(km, qn, lam, False, h, Dhn, Hd)
    K = np.zeros((n + m, n + m))
    M1 = np.empty((n, n))
    N1 = np.empty((n, n))
    N2 = np.empty((n, n))
    q4 = 0.25 * dt
    for i in range(n):
        for j in range(n):
            a = q4 * Lqq[i, j] + q4 * dF_dq[i, j]
            s = 0.5 * (Lqv[i, j] - Lqv[j, i])
            t = 0.5 * (Lqv[i, j] + Lqv[j, i])
            w = Lvv[i, j] / dt
            d = 0.5 * dF_dv[i, j]
            K[i, j] = a + s - w + d                       # M2 = D2D1 L_d + df^-/dq_{k+1}
            M1[i, j] = a - t + w - d - Hk[i, j]            # D1D1 L_d + df^-/dq_k - lambda . D2h(q_k)
            N1[i, j] = a - s - w - d                       # D1D2 L_d + df^+/dq_k
            N2[i, j] = a + t + w + d                       # D2D2 L_d + df^+/dq_{k+1}
        for c in range(m):
            K[i, n + c] = -Dhk[c, i]
            K[n + c, i] = Dhn[c, i]
    Fu = 0.5 * dt * dF_du
    Fc = 0.5 * dt * (dLq_dc + dF_dc)
    return K, M1, N1, N2, Fu, Fc


@njit(cache=True)
def fine_step_linearization(km, coef, dt, qk, qn, lam, u, A, B, Pc):
    """A = dx_{k+1}/dx_k (2n, 2n), B = dx_{k+1}/du (2n, nw), Pc = dx_{k+1}/dcoef (2n, ncoef) for one VI step."""
    n = qk.shape[0]
    m = lam.shape[0]
    nu = u.shape[0]
    nc = coef.shape[0]
    K, M1, N1, N2, Fu, Fc = step_matrices(km, coef, dt, qk, qn, lam, u)
    ncol = n + n + nu + nc
    R = np.zeros((n + m, ncol))
    for i in range(n):
        for j in range(n):
            R[i, j] = -M1[i, j]
        R[i, n + i] = -1.0
        for a2 in range(nu):
            R[i, 2 * n + a2] = -Fu[i, a2]
        for c in range(nc):
            R[i, 2 * n + nu + c] = -Fc[i, c]
    X = np.linalg.solve(K, R)
    Xq = np.ascontiguousarray(X[:n, :])
    NX = N2 @ Xq
    for i in range(n):
        for j in range(n):
            A[i, j] = X[i, j]
            A[i, n + j] = X[i, n + j]
            A[n + i, j] = N1[i, j] + NX[i, j]
            A[n + i, n + j] = NX[i, n + j]
        for a2 in range(nu):
            B[i, a2] = X[i, 2 * n + a2]
            B[n + i, a2] = NX[i, 2 * n + a2] + Fu[i, a2]
        for c in range(nc):
            Pc[i, c] = X[i, 2 * n + nu + c]
            Pc[n + i, c] = NX[i, 2 * n + nu + c] + Fc[i, c]


@njit(cache=True)
def forward_sensitivity_kernel(km, coef, h, Qf, LAMf, Uf, free, S0, S_out, substeps):
    """Forward sensitivities dx/dc of the free coefficients along the VI grid, without forming A:
    solve the bordered system with right-hand side -(M1 S_q + S_p + Fc) per step. S_out: (T, 2n, nfree) at the
    samples (every ``substeps`` VI steps)."""
    n = Qf.shape[1]
    m = LAMf.shape[1]
    nf = free.shape[0]
    S = S0.copy()
    S_out[0] = S
    R = np.zeros((n + m, nf))
    for j in range(Uf.shape[0]):
        K, M1, N1, N2, Fu, Fc = step_matrices(km, coef, h, Qf[j], Qf[j + 1], LAMf[j], Uf[j])
        Sq = np.ascontiguousarray(S[:n])
        Sp = S[n:]
        MS = M1 @ Sq
        for i in range(n):
            for c in range(nf):
                R[i, c] = -(MS[i, c] + Sp[i, c] + Fc[i, free[c]])
        X = np.linalg.solve(K, R)
        Xq = np.ascontiguousarray(X[:n])
        Snew = np.empty_like(S)
        Snew[:n] = Xq
        Snew[n:] = N1 @ Sq + N2 @ Xq
        for i in range(n):
            for c in range(nf):
                Snew[n + i, c] += Fc[i, free[c]]
        S = Snew
        if (j + 1) % substeps == 0:
            S_out[(j + 1) // substeps] = S
    return S


@njit(cache=True)
def adjoint_kernel(km, coef, h, Qf, LAMf, Uf, free, dl_dx, substeps):
    """Discrete adjoint (paper Lemma 1) on the VI grid, without forming A: backward over the steps,
    w = rho_q' + N2^T rho_p', K^T y = (w, 0), rho_q = -M1^T y + N1^T rho_p', rho_p = -y, and the coefficient
    gradient accumulates Fc^T (rho_p' - y). dl_dx: (T, 2n) cost derivatives at the samples.
    Returns (gradient (nfree,), rho_0 (2n,))."""
    n = Qf.shape[1]
    m = LAMf.shape[1]
    nf = free.shape[0]
    steps = Uf.shape[0]
    T = dl_dx.shape[0]
    rho = dl_dx[T - 1].copy()
    grad = np.zeros(nf)
    rhs = np.zeros(n + m)
    for j in range(steps - 1, -1, -1):
        K, M1, N1, N2, Fu, Fc = step_matrices(km, coef, h, Qf[j], Qf[j + 1], LAMf[j], Uf[j])
        rq = rho[:n]
        rp = rho[n:]
        w = rq + N2.T @ rp
        rhs[:n] = w
        rhs[n:] = 0.0
        y = np.linalg.solve(K.T, rhs)
        yn = y[:n]
        for c in range(nf):
            s = 0.0
            for i in range(n):
                s += Fc[i, free[c]] * (rp[i] - yn[i])
            grad[c] += s
        new = np.empty(2 * n)
        new[:n] = -(M1.T @ yn) + N1.T @ rp
        new[n:] = -yn
        rho = new
        if j % substeps == 0:
            rho += dl_dx[j // substeps]
    return grad, rho


@njit(cache=True)
def linearize_kernel(km, coef, h, substeps, Qf, LAMf, Uf, nu, A, B, P):
    """Per sample interval k: A_k, B_k = dx_{k+1}/dtau_k, P_k (composing its ``substeps`` VI steps)."""
    n = Qf.shape[1]
    nw = Uf.shape[1]
    nc = coef.shape[0]
    Aj = np.empty((2 * n, 2 * n))
    Bj = np.empty((2 * n, nw))
    Pj = np.empty((2 * n, nc))
    for k in range(A.shape[0]):
        j0 = k * substeps
        fine_step_linearization(km, coef, h, Qf[j0], Qf[j0 + 1], LAMf[j0], Uf[j0], A[k], Bj, P[k])
        B[k] = Bj[:, :nu]
        for sub in range(1, substeps):
            j = j0 + sub
            fine_step_linearization(km, coef, h, Qf[j], Qf[j + 1], LAMf[j], Uf[j], Aj, Bj, Pj)
            A[k] = Aj @ A[k]
            B[k] = Aj @ B[k] + Bj[:, :nu]
            P[k] = Aj @ P[k] + Pj


@dataclass
class Linearization:
    """Discrete linearization along a trajectory (k = 0..T-2), the tracking feedback (if any) included:
    A[k] = dx_{k+1}/dx_k, B[k] = dx_{k+1}/dtau_k, P[k] = dx_{k+1}/dcoef (all model coefficients)."""
    A: np.ndarray
    B: np.ndarray
    P: np.ndarray


def linearize(model, traj) -> Linearization:
    """Linearize the one-step maps along ``traj`` (with the feedback it was simulated with)."""
    from .variational_integrator import feedback_kernel
    n = model.n
    nu = len(model.input_coords)
    steps = traj.u_fine.shape[0] // traj.substeps
    nc = len(traj.coef)
    A = np.empty((steps, 2 * n, 2 * n))
    B = np.empty((steps, 2 * n, nu))
    P = np.empty((steps, 2 * n, nc))
    linearize_kernel(feedback_kernel(model, traj.feedback), traj.coef, traj.dt / traj.substeps, traj.substeps,
                     traj.q_fine, traj.lam_fine, traj.u_fine, nu, A, B, P)
    return Linearization(A=A, B=B, P=P)


def forward_sensitivities_along(model, traj, free_idx, S0) -> np.ndarray:
    """dx_k/dc (T, 2n, nfree) for the coefficients ``free_idx``, starting from S0 = dx_0/dc (2n, nfree)."""
    from .variational_integrator import feedback_kernel
    T = traj.u_fine.shape[0] // traj.substeps + 1
    S_out = np.empty((T, 2 * model.n, len(free_idx)))
    forward_sensitivity_kernel(feedback_kernel(model, traj.feedback), traj.coef, traj.dt / traj.substeps, traj.q_fine,
                               traj.lam_fine, traj.u_fine, np.asarray(free_idx, dtype=np.int64),
                               np.ascontiguousarray(S0, dtype=float), S_out, traj.substeps)
    return S_out


def adjoint_gradient_along(model, traj, free_idx, S0, dl_dx) -> np.ndarray:
    """dJ/dc for the coefficients ``free_idx`` by the discrete adjoint (Lemma 1); dl_dx: (T, 2n) with the terminal
    cost in the last row; S0 = dx_0/dc (2n, nfree)."""
    from .variational_integrator import feedback_kernel
    grad, rho0 = adjoint_kernel(feedback_kernel(model, traj.feedback), traj.coef, traj.dt / traj.substeps,
                                traj.q_fine, traj.lam_fine, traj.u_fine, np.asarray(free_idx, dtype=np.int64),
                                np.ascontiguousarray(dl_dx, dtype=float), traj.substeps)
    return grad + rho0 @ S0
