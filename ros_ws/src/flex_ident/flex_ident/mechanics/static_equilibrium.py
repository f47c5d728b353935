"""Static equilibrium of the unmeasured coordinates (the loop) with the measured ones (the arm) held, and its
sensitivity to the model coefficients (implicit function theorem).

Recordings start at rest, so the unmeasured object state at t = 0 is the equilibrium for the true parameters
(CONTRACTS.md section 1). Unknowns z = (q_f, mu) (free coordinates, constraint forces); with the arm held:

    grad_f V(q) - F_f(q, 0, 0) + Dh_f(q)^T mu = 0,       h(q) = 0,

Newton with the exact Jacobian [[V_ff - dF_f/dq_f + sum mu_i D2 h_i, Dh_f^T], [Dh_f, 0]]. A continuation moves
the weld targets from where the frames are at the initial guess (e.g. the rest shape) to the real clamp, so any
reachable clamp pose works. The sensitivity dq_f/dc solves the same matrix with right-hand side
-d(grad_f V - F_f)/dc. The torque that holds the arm, u = (grad_a V - F_a + Dh_a^T mu) mapped onto the inputs,
is reported too.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from .tree_kinematics import frame_pose, generalized_forces, lagrangian_derivatives, weld_constraints


class EquilibriumError(ValueError):
    """No static equilibrium: the object cannot be closed onto its clamp from this arm pose."""


@dataclass
class StaticEquilibrium:
    q: np.ndarray               # (n,) configuration (measured coordinates as given)
    mu: np.ndarray              # (m,) constraint forces (welds), N and N m
    holding_torque: np.ndarray  # (nu,) input torques that hold the measured coordinates still [N m]
    dq_dcoef: np.ndarray        # (n, ncoef) sensitivity of q (zero rows for the measured coordinates)
    newton_iterations: int


def _residual_and_jacobian(km, q, mu, coef, free, nu):
    n = q.shape[0]
    nc = coef.shape[0]
    m = mu.shape[0]
    Lq, Lv = np.zeros(n), np.zeros(n)
    Lqq, Lqv, Lvv = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    dLq_dc = np.zeros((n, nc))
    lagrangian_derivatives(km, q, np.zeros(n), coef, True, Lq, Lv, Lqq, Lqv, Lvv, dLq_dc)
    F, dF_dq, dF_dv = np.zeros(n), np.zeros((n, n)), np.zeros((n, n))
    dF_du, dF_dc = np.zeros((n, nu)), np.zeros((n, nc))
    generalized_forces(km, q, np.zeros(n), np.zeros(nu), coef, F, dF_dq, dF_dv, dF_du, dF_dc)
    h, Dh, H = np.zeros(m), np.zeros((m, n)), np.zeros((n, n))
    weld_constraints(km, q, mu, True, h, Dh, H)
    grad = -Lq - F + Dh.T @ mu                         # grad V - F + Dh^T mu, all coordinates
    hess = -Lqq - dF_dq + H
    nf = len(free)
    J = np.zeros((nf + m, nf + m))
    J[:nf, :nf] = hess[np.ix_(free, free)]
    J[:nf, nf:] = Dh[:, free].T
    J[nf:, :nf] = Dh[:, free]
    r = np.concatenate([grad[free], h])
    dr_dc = np.zeros((nf + m, nc))
    dr_dc[:nf] = (-dLq_dc - dF_dc)[free]
    return r, J, dr_dc, grad, Dh


def _newton(km, q, mu, coef, free, nu, tol=1e-11, max_iterations=50):
    nf = len(free)
    for it in range(max_iterations + 1):
        r, J, dr_dc, grad, Dh = _residual_and_jacobian(km, q, mu, coef, free, nu)
        scale = 1.0 + np.abs(grad).max()
        if np.abs(r[:nf]).max(initial=0.0) < tol * scale and np.abs(r[nf:]).max(initial=0.0) < 1e-12:
            try:                    # one more (quadratically convergent) step: full precision for the derivatives
                delta = np.linalg.solve(J, -r)
                q = q.copy()
                q[free] += delta[:nf]
                mu = mu + delta[nf:]
            except np.linalg.LinAlgError:
                pass
            return q, mu, it, True
        try:
            delta = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:
            return q, mu, it, False
        # damped step on large updates keeps Newton inside the basin of the continuation path
        step = 1.0
        big = np.abs(delta[:nf]).max(initial=0.0)
        if big > 0.3:
            step = 0.3 / big
        q = q.copy()
        q[free] += step * delta[:nf]
        mu = mu + step * delta[nf:]
        if not np.all(np.isfinite(q)):
            return q, mu, it, False
    return q, mu, max_iterations, False


def static_equilibrium(model, coef, q_guess, continuation_steps: int = 8) -> StaticEquilibrium:
    """Equilibrium of the non-measured coordinates with the measured ones fixed at ``q_guess``'s values.

    q_guess: (n,) the measured coordinates' values and an initial guess for the others (e.g. the loop's rest
    shape, all zeros). Raises :class:`EquilibriumError` when no equilibrium is found.
    """
    coef = np.asarray(coef, dtype=float)
    n, m = model.n, model.n_constraints
    nu = len(model.input_coords)
    free = np.array([i for i in range(n) if i not in set(model.measured_coords.tolist())], dtype=np.int64)
    q = np.asarray(q_guess, dtype=float).copy()
    mu = np.zeros(m)
    iterations = 0
    if m:
        km0 = model.kernel()
        starts, goals = [], []
        for w in model.welds:
            R, p = frame_pose(km0, q, w.coord, np.ascontiguousarray(w.offset[:3, :3]),
                              np.ascontiguousarray(w.offset[:3, 3]))
            starts.append((R, p))
            goals.append((w.target[:3, :3], w.target[:3, 3]))
        slerps = [Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([s[0], g[0]]))) for s, g in zip(starts, goals)]
        s_done, ds = 0.0, 1.0 / continuation_steps
        while s_done < 1.0 - 1e-12:
            s = min(1.0, s_done + ds)
            targets = []
            for (R0, p0), (R1, p1), sl in zip(starts, goals, slerps):
                g = np.eye(4)
                g[:3, :3] = sl([s]).as_matrix()[0]
                g[:3, 3] = (1 - s) * p0 + s * p1
                targets.append(g)
            km = model.with_weld_targets(targets).kernel() if s < 1.0 else model.kernel()
            q_new, mu_new, it, ok = _newton(km, q, mu, coef, free, nu)
            iterations += it
            if ok:
                q, mu, s_done = q_new, mu_new, s
                ds = min(2 * ds, 0.5)
            else:
                ds *= 0.5
                if ds < 1e-3:
                    raise EquilibriumError(_failure_message(model, q_guess))
    else:
        q, mu, it, ok = _newton(model.kernel(), q, mu, coef, free, nu)
        iterations += it
        if not ok:
            raise EquilibriumError('no static equilibrium found for the unmeasured coordinates')
    r, J, dr_dc, grad, Dh = _residual_and_jacobian(model.kernel(), q, mu, coef, free, nu)
    nf = len(free)
    dz = -np.linalg.solve(J, dr_dc)
    dq = np.zeros((n, len(coef)))
    dq[free] = dz[:nf]
    # holding torque: grad_a V - F_a(u=0) + Dh_a^T mu = (input map) u
    Bu = np.zeros((n, nu))
    for a, i in enumerate(model.input_coords):
        Bu[i, a] = 1.0 if model.input_gain_coef[a] < 0 else coef[model.input_gain_coef[a]]
    hold = np.linalg.lstsq(Bu, grad, rcond=None)[0]
    return StaticEquilibrium(q=q, mu=mu, holding_torque=hold, dq_dcoef=dq, newton_iterations=iterations)


def _failure_message(model, q_guess) -> str:
    msg = 'no static equilibrium found: the object cannot be closed onto its clamp from the initial arm pose'
    if 'ee' in model.frames and model.welds:
        km = model.kernel()
        c, off = model.frames['ee']
        _, p = frame_pose(km, np.asarray(q_guess, float), c, np.ascontiguousarray(off[:3, :3]),
                          np.ascontiguousarray(off[:3, 3]))
        clamp = model.welds[0].target[:3, 3]
        reach = model.description.get('loop_links', 0) / 2 * model.description.get('loop_link_length_m', 0.0)
        msg += (f' (grasp point {np.round(p, 3).tolist()} m is {np.linalg.norm(p - clamp):.3f} m from the clamp '
                f'{np.round(clamp, 3).tolist()} m'
                + (f'; each loop branch reaches at most {reach:.3f} m' if reach else '') + ')')
    return msg
