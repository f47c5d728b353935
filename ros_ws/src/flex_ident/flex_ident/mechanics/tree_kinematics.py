"""Compiled (numba) recursions over the tree of coordinates: kinematics, Lagrangian derivatives, welds, forces.

Spatial (base-frame) formulation, twists ordered (v; w). For coordinate i with spatial twist xi_i, the velocity of
the frame after i is U_i = sum_{j <= i} xi_j qdot_j (j <= i: j is i or an ancestor of i), and moving an ancestor j
rotates everything below it: d xi_i / d q_j = ad(xi_j) xi_i. With the composite spatial inertia Mc_i and momentum
Pc_i of the subtree below i (bodies at the base origin), c_i = ad(xi_i) U_i, MX_i = Mc_i xi_i and
beta_i = Mc_i c_i + ad(xi_i)^T Pc_i, the Lagrangian L = T - V has, for j <= i,

    dL/dqdot_i = xi_i . Pc_i                          dL/dq_i = -Pc_i . c_i + g . MX_i[:3]   (+ springs)
    d2L/dqdot_i dqdot_j = xi_j . MX_i                 d2L/dq_i dq_j = c_j . beta_i - MX_i[:3] . (w_j x g)
    d2L/dq_i dqdot_j = -xi_j . beta_i                 d2L/dq_j dqdot_i = -c_j . MX_i   (j strictly above i)

and zero for coordinates on different branches (O(n x depth) work; Johnson and Murphey exploit the same tree
sparsity with cached frame derivatives). Every formula is checked against finite differences in the tests.

Welds: h = (p_F - p_T, vee(skew(R_T^T R_F))), 6 per weld, with first and lambda-weighted second derivatives.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from .model import ConstantForce, CoulombFriction, MechanicalModel, Spring, ViscousDamping

KernelModel = namedtuple('KernelModel', [
    'parent', 'order', 'jtype', 'XR', 'Xp', 'axis', 'anc', 'ancl', 'nanc',
    'bmass', 'bcom', 'binertia', 'gravity',
    'weld_coord', 'weld_XR', 'weld_Xp', 'weld_RT', 'weld_pT',
    'spring_coord', 'spring_coef', 'spring_rest', 'spring_rest_coef',
    'visc_coord', 'visc_coef',
    'coul_coord', 'coul_coef', 'coul_vs',
    'cforce_coord', 'cforce_coef',
    'input_coord', 'input_gain_coef', 'ncoef',
    'measured', 'fb_Kp', 'fb_Kd'])


def _topological_order(parent: np.ndarray) -> np.ndarray:
    n = len(parent)
    depth = np.full(n, -1)

    def d(i, seen=()):
        if depth[i] >= 0:
            return depth[i]
        if i in seen:
            raise ValueError('the coordinate tree has a cycle')
        depth[i] = 0 if parent[i] < 0 else d(parent[i], seen + (i,)) + 1
        return depth[i]

    for i in range(n):
        d(i)
    return np.argsort(depth, kind='stable').astype(np.int64)


def pack_model(model: MechanicalModel) -> KernelModel:
    """Arrays for the compiled kernels (see :class:`KernelModel`)."""
    n = model.n
    parent = model.parent.astype(np.int64)
    order = _topological_order(parent)
    anc = np.zeros((n, n), dtype=np.bool_)
    ancl_lists = []
    for i in range(n):
        chain = []
        j = i
        while j >= 0:
            chain.append(j)
            anc[i, j] = True
            j = parent[j]
        ancl_lists.append(chain[::-1])
    depth = max(len(a) for a in ancl_lists) if n else 1
    ancl = np.full((n, depth), -1, dtype=np.int64)
    nanc = np.zeros(n, dtype=np.int64)
    for i, chain in enumerate(ancl_lists):
        ancl[i, :len(chain)] = chain
        nanc[i] = len(chain)

    def ints(xs):
        return np.array(xs, dtype=np.int64).reshape(-1)

    def floats(xs):
        return np.array(xs, dtype=np.float64).reshape(-1)

    terms = model.terms
    springs = [t for t in terms if isinstance(t, Spring)]
    visc = [t for t in terms if isinstance(t, ViscousDamping)]
    coul = [t for t in terms if isinstance(t, CoulombFriction)]
    cforce = [t for t in terms if isinstance(t, ConstantForce)]
    unknown = [t for t in terms if not isinstance(t, (Spring, ViscousDamping, CoulombFriction, ConstantForce))]
    if unknown:
        raise TypeError(f'model terms without a compiled kernel: {unknown}')
    nw = len(model.welds)
    weld_XR = np.zeros((nw, 3, 3))
    weld_Xp = np.zeros((nw, 3))
    weld_RT = np.zeros((nw, 3, 3))
    weld_pT = np.zeros((nw, 3))
    for k, w in enumerate(model.welds):
        weld_XR[k], weld_Xp[k] = w.offset[:3, :3], w.offset[:3, 3]
        weld_RT[k], weld_pT[k] = w.target[:3, :3], w.target[:3, 3]
    return KernelModel(
        parent=parent, order=order, jtype=model.jtype.astype(np.int64),
        XR=np.ascontiguousarray(model.origin[:, :3, :3]), Xp=np.ascontiguousarray(model.origin[:, :3, 3]),
        axis=np.ascontiguousarray(model.axis, dtype=np.float64), anc=anc, ancl=ancl, nanc=nanc,
        bmass=model.body_mass.astype(np.float64), bcom=np.ascontiguousarray(model.body_com, dtype=np.float64),
        binertia=np.ascontiguousarray(model.body_inertia, dtype=np.float64),
        gravity=np.asarray(model.gravity, dtype=np.float64),
        weld_coord=ints([w.coord for w in model.welds]), weld_XR=weld_XR, weld_Xp=weld_Xp,
        weld_RT=weld_RT, weld_pT=weld_pT,
        spring_coord=ints([t.coord for t in springs]), spring_coef=ints([t.coef for t in springs]),
        spring_rest=floats([t.rest for t in springs]), spring_rest_coef=ints([t.rest_coef for t in springs]),
        visc_coord=ints([t.coord for t in visc]), visc_coef=ints([t.coef for t in visc]),
        coul_coord=ints([t.coord for t in coul]), coul_coef=ints([t.coef for t in coul]),
        coul_vs=floats([t.velocity_scale for t in coul]),
        cforce_coord=ints([t.coord for t in cforce]), cforce_coef=ints([t.coef for t in cforce]),
        input_coord=model.input_coords.astype(np.int64), input_gain_coef=model.input_gain_coef.astype(np.int64),
        ncoef=len(model.coefficients),
        measured=model.measured_coords.astype(np.int64),
        fb_Kp=np.zeros((len(model.measured_coords), len(model.measured_coords))),
        fb_Kd=np.zeros((len(model.measured_coords), len(model.measured_coords))))


# ----------------------------------------------------------------------------------------------------------------
# small fixed-size helpers
# ----------------------------------------------------------------------------------------------------------------

@njit(cache=True, inline='always')
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=True, inline='always')
def _dot6(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5]


@njit(cache=True)
def _ad(xi, eta, out):
    """out = ad(xi) eta = (w x eta_v + v x eta_w ; w x eta_w) for xi = (v; w)."""
    v0, v1, v2, w0, w1, w2 = xi[0], xi[1], xi[2], xi[3], xi[4], xi[5]
    a0, a1, a2, b0, b1, b2 = eta[0], eta[1], eta[2], eta[3], eta[4], eta[5]
    out[0] = w1 * a2 - w2 * a1 + v1 * b2 - v2 * b1
    out[1] = w2 * a0 - w0 * a2 + v2 * b0 - v0 * b2
    out[2] = w0 * a1 - w1 * a0 + v0 * b1 - v1 * b0
    out[3] = w1 * b2 - w2 * b1
    out[4] = w2 * b0 - w0 * b2
    out[5] = w0 * b1 - w1 * b0


@njit(cache=True)
def _ad_transpose(xi, P, out):
    """out = ad(xi)^T P for a wrench P = (f; tau): (f x w ; f x v + tau x w)."""
    v0, v1, v2, w0, w1, w2 = xi[0], xi[1], xi[2], xi[3], xi[4], xi[5]
    f0, f1, f2, t0, t1, t2 = P[0], P[1], P[2], P[3], P[4], P[5]
    out[0] = f1 * w2 - f2 * w1
    out[1] = f2 * w0 - f0 * w2
    out[2] = f0 * w1 - f1 * w0
    out[3] = f1 * v2 - f2 * v1 + t1 * w2 - t2 * w1
    out[4] = f2 * v0 - f0 * v2 + t2 * w0 - t0 * w2
    out[5] = f0 * v1 - f1 * v0 + t0 * w1 - t1 * w0


@njit(cache=True)
def _rodrigues(axis, angle, out):
    c = np.cos(angle)
    s = np.sin(angle)
    t = 1.0 - c
    x, y, z = axis[0], axis[1], axis[2]
    out[0, 0] = c + x * x * t
    out[0, 1] = x * y * t - z * s
    out[0, 2] = x * z * t + y * s
    out[1, 0] = y * x * t + z * s
    out[1, 1] = c + y * y * t
    out[1, 2] = y * z * t - x * s
    out[2, 0] = z * x * t - y * s
    out[2, 1] = z * y * t + x * s
    out[2, 2] = c + z * z * t


@njit(cache=True, inline='always')
def _mm3(A, B, out):
    for r in range(3):
        for c in range(3):
            out[r, c] = A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c]


@njit(cache=True, inline='always')
def _mv3(A, x, out):
    for r in range(3):
        out[r] = A[r, 0] * x[0] + A[r, 1] * x[1] + A[r, 2] * x[2]


# ----------------------------------------------------------------------------------------------------------------
# kinematics
# ----------------------------------------------------------------------------------------------------------------

@njit(cache=True)
def forward_kinematics(km, q, R, p, xi):
    """Frames (R[i], p[i]) of every coordinate (after its joint motion) and spatial twists xi[i] (base frame)."""
    RJ = np.empty((3, 3))
    Rq = np.empty((3, 3))
    pJ = np.empty(3)
    w = np.empty(3)
    tmp = np.empty(3)
    for i in km.order:
        par = km.parent[i]
        if par < 0:
            RJ[:, :] = km.XR[i]
            pJ[:] = km.Xp[i]
        else:
            _mm3(R[par], km.XR[i], RJ)
            _mv3(R[par], km.Xp[i], tmp)
            pJ[0] = p[par, 0] + tmp[0]
            pJ[1] = p[par, 1] + tmp[1]
            pJ[2] = p[par, 2] + tmp[2]
        _mv3(RJ, km.axis[i], w)
        if km.jtype[i] == 0:
            _cross(pJ, w, tmp)
            xi[i, 0], xi[i, 1], xi[i, 2] = tmp[0], tmp[1], tmp[2]
            xi[i, 3], xi[i, 4], xi[i, 5] = w[0], w[1], w[2]
            _rodrigues(km.axis[i], q[i], Rq)
            _mm3(RJ, Rq, R[i])
            p[i, 0], p[i, 1], p[i, 2] = pJ[0], pJ[1], pJ[2]
        else:
            xi[i, 0], xi[i, 1], xi[i, 2] = w[0], w[1], w[2]
            xi[i, 3] = 0.0
            xi[i, 4] = 0.0
            xi[i, 5] = 0.0
            R[i, :, :] = RJ
            p[i, 0] = pJ[0] + w[0] * q[i]
            p[i, 1] = pJ[1] + w[1] * q[i]
            p[i, 2] = pJ[2] + w[2] * q[i]


@njit(cache=True)
def frame_pose(km, q, coord, XR, Xp):
    """Pose (R, p) of a frame attached to ``coord`` with offset (XR, Xp); coord -1 means the base."""
    n = q.shape[0]
    R = np.empty((n, 3, 3))
    p = np.empty((n, 3))
    xi = np.empty((n, 6))
    forward_kinematics(km, q, R, p, xi)
    RF = np.empty((3, 3))
    pF = np.empty(3)
    if coord < 0:
        RF[:, :] = XR
        pF[:] = Xp
    else:
        _mm3(R[coord], XR, RF)
        _mv3(R[coord], Xp, pF)
        pF += p[coord]
    return RF, pF


@njit(cache=True)
def point_position_jacobian(km, q, coord, Xp, y, C):
    """Position y (3,) of a point fixed in coordinate ``coord``'s frame at Xp, and its Jacobian C (3, n)."""
    n = q.shape[0]
    R = np.empty((n, 3, 3))
    p = np.empty((n, 3))
    xi = np.empty((n, 6))
    forward_kinematics(km, q, R, p, xi)
    _mv3(R[coord], Xp, y)
    y += p[coord]
    C[:, :] = 0.0
    tmp = np.empty(3)
    for a in range(km.nanc[coord]):
        i = km.ancl[coord, a]
        _cross(xi[i, 3:6], y, tmp)
        C[0, i] = xi[i, 0] + tmp[0]
        C[1, i] = xi[i, 1] + tmp[1]
        C[2, i] = xi[i, 2] + tmp[2]


# ----------------------------------------------------------------------------------------------------------------
# Lagrangian
# ----------------------------------------------------------------------------------------------------------------

@njit(cache=True)
def _body_spatial_inertia(m, com_local, I_local, R, p, out):
    """6x6 spatial inertia about the base origin of a body at pose (R, p), twist order (v; w) (no allocation)."""
    c0 = p[0] + R[0, 0] * com_local[0] + R[0, 1] * com_local[1] + R[0, 2] * com_local[2]
    c1 = p[1] + R[1, 0] * com_local[0] + R[1, 1] * com_local[1] + R[1, 2] * com_local[2]
    c2 = p[2] + R[2, 0] * com_local[0] + R[2, 1] * com_local[1] + R[2, 2] * com_local[2]
    for r in range(6):
        for s in range(6):
            out[r, s] = 0.0
    out[0, 0] = m
    out[1, 1] = m
    out[2, 2] = m
    # upper right: -m [c]x ; lower left: m [c]x
    out[0, 4] = m * c2
    out[0, 5] = -m * c1
    out[1, 3] = -m * c2
    out[1, 5] = m * c0
    out[2, 3] = m * c1
    out[2, 4] = -m * c0
    out[3, 1] = -m * c2
    out[3, 2] = m * c1
    out[4, 0] = m * c2
    out[4, 2] = -m * c0
    out[5, 0] = -m * c1
    out[5, 1] = m * c0
    # lower right: R I R^T + m (|c|^2 I - c c^T)
    cc = c0 * c0 + c1 * c1 + c2 * c2
    for r in range(3):
        a0 = R[r, 0] * I_local[0, 0] + R[r, 1] * I_local[1, 0] + R[r, 2] * I_local[2, 0]
        a1 = R[r, 0] * I_local[0, 1] + R[r, 1] * I_local[1, 1] + R[r, 2] * I_local[2, 1]
        a2 = R[r, 0] * I_local[0, 2] + R[r, 1] * I_local[1, 2] + R[r, 2] * I_local[2, 2]
        cr = c0 if r == 0 else (c1 if r == 1 else c2)
        for s in range(3):
            cs = c0 if s == 0 else (c1 if s == 1 else c2)
            out[3 + r, 3 + s] = a0 * R[s, 0] + a1 * R[s, 1] + a2 * R[s, 2] - m * cr * cs
        out[3 + r, 3 + r] += m * cc


@njit(cache=True)
def lagrangian_derivatives(km, q, v, coef, second, Lq, Lv, Lqq, Lqv, Lvv, dLq_dc):
    """Derivatives of L(q, qdot) = T - V at (q, v).

    Fills Lq = dL/dq, Lv = dL/dqdot, dLq_dc = d(dL/dq)/d coef (n, ncoef) and, when ``second``,
    Lqq = d2L/dq2, Lqv[i, j] = d2L/dq_i dqdot_j, Lvv = d2L/dqdot2 (the mass matrix). Returns (T, V).
    """
    n = q.shape[0]
    R = np.empty((n, 3, 3))
    p = np.empty((n, 3))
    xi = np.empty((n, 6))
    forward_kinematics(km, q, R, p, xi)
    U = np.empty((n, 6))
    c = np.empty((n, 6))
    Mc = np.empty((n, 6, 6))
    Pc = np.zeros((n, 6))
    g = km.gravity
    kinetic = 0.0
    potential = 0.0
    com = np.empty(3)
    for i in km.order:
        par = km.parent[i]
        for r in range(6):
            U[i, r] = (U[par, r] if par >= 0 else 0.0) + xi[i, r] * v[i]
        _ad(xi[i], U[i], c[i])
        _body_spatial_inertia(km.bmass[i], km.bcom[i], km.binertia[i], R[i], p[i], Mc[i])
        for r in range(6):
            s = 0.0
            for t in range(6):
                s += Mc[i, r, t] * U[i, t]
            Pc[i, r] = s
        kinetic += 0.5 * _dot6(U[i], Pc[i])
        # gravity potential of this body: -m g . com_world
        _mv3(R[i], km.bcom[i], com)
        potential -= km.bmass[i] * (g[0] * (com[0] + p[i, 0]) + g[1] * (com[1] + p[i, 1]) + g[2] * (com[2] + p[i, 2]))
    for a in range(n - 1, -1, -1):
        i = km.order[a]
        par = km.parent[i]
        if par >= 0:
            for r in range(6):
                Pc[par, r] += Pc[i, r]
                for t in range(6):
                    Mc[par, r, t] += Mc[i, r, t]
    MX = np.empty((n, 6))
    beta = np.empty((n, 6))
    tmp6 = np.empty(6)
    for i in range(n):
        for r in range(6):
            s1 = 0.0
            s2 = 0.0
            for t in range(6):
                s1 += Mc[i, r, t] * xi[i, t]
                s2 += Mc[i, r, t] * c[i, t]
            MX[i, r] = s1
            beta[i, r] = s2
        _ad_transpose(xi[i], Pc[i], tmp6)
        for r in range(6):
            beta[i, r] += tmp6[r]
        Lv[i] = _dot6(xi[i], Pc[i])
        Lq[i] = -_dot6(Pc[i], c[i]) + g[0] * MX[i, 0] + g[1] * MX[i, 1] + g[2] * MX[i, 2]
    dLq_dc[:, :] = 0.0
    if second:
        Lvv[:, :] = 0.0
        Lqq[:, :] = 0.0
        Lqv[:, :] = 0.0
        wg = np.empty(3)
        for i in range(n):
            for a in range(km.nanc[i]):
                j = km.ancl[i, a]
                _cross(xi[j, 3:6], g, wg)
                mij = _dot6(xi[j], MX[i])
                Lvv[i, j] = mij
                Lvv[j, i] = mij
                qq = _dot6(c[j], beta[i]) - (MX[i, 0] * wg[0] + MX[i, 1] * wg[1] + MX[i, 2] * wg[2])
                Lqq[i, j] = qq
                Lqq[j, i] = qq
                Lqv[i, j] = -_dot6(xi[j], beta[i])
                if j != i:
                    Lqv[j, i] = -_dot6(c[j], MX[i])
    for s in range(km.spring_coord.shape[0]):
        i = km.spring_coord[s]
        k = coef[km.spring_coef[s]]
        d = q[i] - km.spring_rest[s]
        rc = km.spring_rest_coef[s]
        if rc >= 0:
            d -= coef[rc]
            dLq_dc[i, rc] += k
        Lq[i] -= k * d
        dLq_dc[i, km.spring_coef[s]] -= d
        potential += 0.5 * k * d * d
        if second:
            Lqq[i, i] -= k
    return kinetic, potential


@njit(cache=True)
def generalized_forces(km, q, v, u, coef, F, dF_dq, dF_dv, dF_du, dF_dc):
    """Generalized forces F(q, qdot, u; coef) and their derivatives.

    u = (tau (nu), theta_ref (na), theta_rate_ref (na)): the input torques, then the reference angles and rates of the
    tracking feedback tau_fb = Kp (theta_ref - q[measured]) + Kd (theta_rate_ref - qdot[measured]) (km.fb_Kp, fb_Kd;
    zero gains: no feedback). Then the dissipative/bias terms of the model (viscous, Coulomb, constant forces).
    """
    F[:] = 0.0
    dF_dq[:, :] = 0.0
    dF_dv[:, :] = 0.0
    dF_du[:, :] = 0.0
    dF_dc[:, :] = 0.0
    nu = km.input_coord.shape[0]
    na = km.measured.shape[0]
    for a in range(nu):
        i = km.input_coord[a]
        gc = km.input_gain_coef[a]
        gain = coef[gc] if gc >= 0 else 1.0
        F[i] += gain * u[a]
        dF_du[i, a] += gain
        if gc >= 0:
            dF_dc[i, gc] += u[a]
    if u.shape[0] >= nu + 2 * na:
        for a in range(na):
            i = km.measured[a]
            for b in range(na):
                kp = km.fb_Kp[a, b]
                kd = km.fb_Kd[a, b]
                if kp == 0.0 and kd == 0.0:
                    continue
                j = km.measured[b]
                F[i] += kp * (u[nu + b] - q[j]) + kd * (u[nu + na + b] - v[j])
                dF_dq[i, j] -= kp
                dF_dv[i, j] -= kd
                dF_du[i, nu + b] += kp
                dF_du[i, nu + na + b] += kd
    for s in range(km.visc_coord.shape[0]):
        i = km.visc_coord[s]
        k = km.visc_coef[s]
        F[i] -= coef[k] * v[i]
        dF_dv[i, i] -= coef[k]
        dF_dc[i, k] -= v[i]
    for s in range(km.coul_coord.shape[0]):
        i = km.coul_coord[s]
        k = km.coul_coef[s]
        th = np.tanh(v[i] / km.coul_vs[s])
        F[i] -= coef[k] * th
        dF_dv[i, i] -= coef[k] * (1.0 - th * th) / km.coul_vs[s]
        dF_dc[i, k] -= th
    for s in range(km.cforce_coord.shape[0]):
        i = km.cforce_coord[s]
        k = km.cforce_coef[s]
        F[i] += coef[k]
        dF_dc[i, k] += 1.0


# ----------------------------------------------------------------------------------------------------------------
# welds (holonomic constraints)
# ----------------------------------------------------------------------------------------------------------------

@njit(cache=True)
def weld_constraints(km, q, lam, hessian, h, Dh, H):
    """h(q) (6 per weld), Dh (m, n) and, when ``hessian``, H = sum_c lam_c D2 h_c (n, n)."""
    n = q.shape[0]
    R = np.empty((n, 3, 3))
    p = np.empty((n, 3))
    xi = np.empty((n, 6))
    forward_kinematics(km, q, R, p, xi)
    Dh[:, :] = 0.0
    if hessian:
        H[:, :] = 0.0
    RF = np.empty((3, 3))
    pF = np.empty(3)
    A = np.empty((3, 3))
    B = np.empty((3, 3))
    Lam = np.empty((3, 3))
    tmp = np.empty(3)
    nw = km.weld_coord.shape[0]
    Jp = np.empty((n, 3))
    av = np.empty((n, 3))
    for w in range(nw):
        a = km.weld_coord[w]
        _mm3(R[a], km.weld_XR[w], RF)
        _mv3(R[a], km.weld_Xp[w], pF)
        pF += p[a]
        RT = km.weld_RT[w]
        for r in range(3):
            for s in range(3):
                A[r, s] = RT[0, r] * RF[0, s] + RT[1, r] * RF[1, s] + RT[2, r] * RF[2, s]
        r0 = 6 * w
        for r in range(3):
            h[r0 + r] = pF[r] - km.weld_pT[w, r]
        h[r0 + 3] = 0.5 * (A[2, 1] - A[1, 2])
        h[r0 + 4] = 0.5 * (A[0, 2] - A[2, 0])
        h[r0 + 5] = 0.5 * (A[1, 0] - A[0, 1])
        for b in range(km.nanc[a]):
            i = km.ancl[a, b]
            _cross(xi[i, 3:6], pF, tmp)
            for r in range(3):
                Jp[i, r] = xi[i, r] + tmp[r]
                Dh[r0 + r, i] = Jp[i, r]
            # a_i = RT^T w_i ; orientation column = vee(skew([a_i] A))
            for r in range(3):
                av[i, r] = RT[0, r] * xi[i, 3] + RT[1, r] * xi[i, 4] + RT[2, r] * xi[i, 5]
            x, y, z = av[i, 0], av[i, 1], av[i, 2]
            for s in range(3):
                B[0, s] = -z * A[1, s] + y * A[2, s]
                B[1, s] = z * A[0, s] - x * A[2, s]
                B[2, s] = -y * A[0, s] + x * A[1, s]
            Dh[r0 + 3, i] = 0.5 * (B[2, 1] - B[1, 2])
            Dh[r0 + 4, i] = 0.5 * (B[0, 2] - B[2, 0])
            Dh[r0 + 5, i] = 0.5 * (B[1, 0] - B[0, 1])
        if hessian:
            lp0, lp1, lp2 = lam[r0], lam[r0 + 1], lam[r0 + 2]
            lr0, lr1, lr2 = lam[r0 + 3], lam[r0 + 4], lam[r0 + 5]
            # Lam = A [lr]x
            for r in range(3):
                Lam[r, 0] = A[r, 1] * lr2 - A[r, 2] * lr1
                Lam[r, 1] = -A[r, 0] * lr2 + A[r, 2] * lr0
                Lam[r, 2] = A[r, 0] * lr1 - A[r, 1] * lr0
            trL = Lam[0, 0] + Lam[1, 1] + Lam[2, 2]
            for b in range(km.nanc[a]):
                i = km.ancl[a, b]
                for e in range(b + 1):
                    j = km.ancl[a, e]
                    # position: lam_p . (w_j x Jp_i) = Jp_i . (lam_p x w_j)
                    w0, w1, w2 = xi[j, 3], xi[j, 4], xi[j, 5]
                    c0 = lp1 * w2 - lp2 * w1
                    c1 = lp2 * w0 - lp0 * w2
                    c2 = lp0 * w1 - lp1 * w0
                    val = Jp[i, 0] * c0 + Jp[i, 1] * c1 + Jp[i, 2] * c2
                    # orientation: -1/2 (a_j^T Lam a_i - (a_i . a_j) tr Lam)
                    s = 0.0
                    for r in range(3):
                        s += av[j, r] * (Lam[r, 0] * av[i, 0] + Lam[r, 1] * av[i, 1] + Lam[r, 2] * av[i, 2])
                    aa = av[i, 0] * av[j, 0] + av[i, 1] * av[j, 1] + av[i, 2] * av[j, 2]
                    val += -0.5 * (s - aa * trL)
                    H[i, j] += val
                    if j != i:
                        H[j, i] += val


@njit(cache=True)
def point_positions(km, Q, coord, Xp, Y, C):
    """Positions Y (T, 3) and Jacobians C (T, 3, n) of a point fixed in ``coord``'s frame along configurations Q."""
    for k in range(Q.shape[0]):
        point_position_jacobian(km, Q[k], coord, Xp, Y[k], C[k])
