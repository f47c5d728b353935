"""Gradient of the discrete cost with respect to the coefficients (paper Lemma 1) and forward sensitivities.

With the closed-loop linearization x_{k+1} = A_k x_k + P_k dc (see mechanics.linearization) and the sensitivity of
the initial state S_0 = dx_0/dc (static equilibrium, implicit function theorem):

* adjoint (Lemma 1, Eq. 9-10): rho_{T-1} = dm/dx_{T-1}, rho_k = dl_k/dx_k + A_k^T rho_{k+1},
  dJ/dc = sum_{k=0}^{T-2} rho_{k+1}^T P_k + rho_0^T S_0 (+ dl/dc, zero here): one backward pass for all parameters.
* forward: S_{k+1} = A_k S_k + P_k, giving the residual Jacobian dr_k/dc = C_k S_k[:n] for Gauss-Newton.

Both routes agree to rounding (tested), and both are checked against finite differences of the whole simulation.
"""
from __future__ import annotations

import numpy as np

from ..mechanics.tree_kinematics import generalized_forces, lagrangian_derivatives


def initial_state_sensitivity(model, coef, h, q0, u0, dq0_dcoef) -> np.ndarray:
    """S_0 = dx_0/dc (2n, ncoef) for x_0 = (q_0, p_0), p_0 = D2 L_d(q_0, q_0) + f^+ = (h/2)(L_q + F)(q_0, 0, u_0).

    dq0_dcoef: (n, ncoef) from the static equilibrium (zero rows for the held arm angles, so u_0's feedback term
    does not move). h: the VI step.
    """
    n = model.n
    nc = len(coef)
    nu = len(model.input_coords)
    Lq, Lv = np.zeros(n), np.zeros(n)
    Lqq, Lqv, Lvv = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    dLq_dc = np.zeros((n, nc))
    km = model.kernel()
    q0 = np.asarray(q0, float)
    coef = np.asarray(coef, float)
    lagrangian_derivatives(km, q0, np.zeros(n), coef, True, Lq, Lv, Lqq, Lqv, Lvv, dLq_dc)
    F, dF_dq, dF_dv = np.zeros(n), np.zeros((n, n)), np.zeros((n, n))
    dF_du, dF_dc = np.zeros((n, nu)), np.zeros((n, nc))
    generalized_forces(km, q0, np.zeros(n), np.asarray(u0, float), coef, F, dF_dq, dF_dv, dF_du, dF_dc)
    S0 = np.zeros((2 * n, nc))
    S0[:n] = dq0_dcoef
    S0[n:] = 0.5 * h * ((Lqq + dF_dq) @ dq0_dcoef + dLq_dc + dF_dc)
    return S0


def forward_sensitivities(A, P, S0) -> np.ndarray:
    """S_k = dx_k/dc for k = 0..T-1: S_{k+1} = A_k S_k + P_k."""
    steps = A.shape[0]
    S = np.empty((steps + 1,) + S0.shape)
    S[0] = S0
    for k in range(steps):
        S[k + 1] = A[k] @ S[k] + P[k]
    return S


def adjoint_gradient(A, P, S0, dl_dx) -> np.ndarray:
    """dJ/dc for J = sum_k l_k(x_k) (the terminal cost included as the last l) by the discrete adjoint.

    dl_dx: (T, 2n) derivative of each sample's cost with respect to x_k (the last row is dm/dx_{T-1}).
    """
    steps = A.shape[0]
    rho = dl_dx[steps].copy()
    grad = np.zeros(P.shape[2])
    for k in range(steps - 1, -1, -1):
        grad += rho @ P[k]
        rho = dl_dx[k] + rho @ A[k]
    return grad + rho @ S0


def cost_state_gradient(r, C, n) -> np.ndarray:
    """dl_k/dx_k (T, 2n) for l_k = |r_k|^2 with r_k depending on q_k through C_k = dr_k/dq_k."""
    out = np.zeros((r.shape[0], 2 * n))
    out[:, :n] = 2.0 * np.einsum('kd,kdn->kn', r, C)
    return out


def residual_jacobian(S, C, n) -> np.ndarray:
    """dr/dc (T*d, ncoef) from forward sensitivities S (T, 2n, nc) and output Jacobians C (T, d, n)."""
    return np.einsum('kdn,knc->kdc', C, S[:, :n, :]).reshape(-1, S.shape[2])
