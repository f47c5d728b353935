"""Discrete elastic rod energies with analytic gradients and Hessians (paper Eq. 2-4; Bergou et al. 2008, 2010).

Degrees of freedom q = [x_0, theta^0, x_1, theta^1, ..., x_{N-1}, theta^{N-1}, x_N] (size 4N + 3): node positions
and edge twist angles.  The bending and twisting stencil of interior node i (1..N-1) is the contiguous block
q[4(i-1) : 4(i-1) + 11] = (x_{i-1}, theta^{i-1}, x_i, theta^i, x_{i+1}); edge j's stretching involves x_j and x_{j+1}.

* stretching  E_s = ks/2 sum_j |e~^j| (|e^j| / |e~^j| - 1)^2                                      (Eq. 2)
* bending     E_b = EI/2 sum_i ((kappa1_i - kappa1~_i)^2 + (kappa2_i - kappa2~_i)^2) / l_i       (Eq. 3)
* twisting    E_t = GJ/2 sum_i (tau_i - tau~_i)^2 / l_i,  tau_i = theta^i - theta^{i-1} + reference twist (Eq. 4)

with the Voronoi length l_i = (|e~^{i-1}| + |e~^i|) / 2 and the material curvatures kappa1 = (m2^{i-1} + m2^i) . kb / 2,
kappa2 = -(m1^{i-1} + m1^i) . kb / 2, kb = 2 e^{i-1} x e^i / (|e^{i-1}||e^i| + e^{i-1} . e^i).
Gradients and Hessians are those of the energy with reference frames carried by time-parallel transport (the
standard DER linearisation); ``test_der_energy.py`` checks both against finite differences.

Compiled with numba (``cache=True``: the first use in a fresh checkout compiles for about 9 s of CPU, then loads from
``__pycache__``): one loop over the elements computes each element's energy, gradient and Hessian block in place and
adds them either to per-element arrays (the ``stretching``, ``bending``, ``twisting`` functions, for tests and
diagnostics) or straight into LAPACK band storage (``elastic_banded``, what the simulator calls each Newton
iteration), with no per-element Python work and no temporaries.
"""
import numpy as np
from numba import njit

BAND = 10          # half-bandwidth of the Hessian in this DOF order (a stencil spans 11 consecutive DOFs)


def positions(q):
    """Node positions (N+1, 3) from the DOF vector."""
    n_nodes = (len(q) + 1) // 4
    idx = 4 * np.arange(n_nodes)[:, None] + np.arange(3)[None, :]
    return q[idx]


def thetas(q):
    n_edges = (len(q) - 3) // 4
    return q[4 * np.arange(n_edges) + 3]


def node_dofs(n_nodes):
    return 4 * np.arange(n_nodes)[:, None] + np.arange(3)[None, :]


def stretching_dofs(n_edges):
    """Global DOF indices (N, 6) of the stretching blocks."""
    nd = node_dofs(n_edges + 1)
    return np.concatenate([nd[:-1], nd[1:]], axis=1)


def stencil_dofs(n_edges):
    """Global DOF indices (N-1, 11) of the bending/twisting stencils."""
    return 4 * np.arange(n_edges - 1)[:, None] + np.arange(11)[None, :]


# ------------------------------------------------------------------------------------------------ element kernels
@njit(cache=True)
def _stretch_element(q, j, rest, ks, hessian, g, H):
    """Energy of edge j; its gradient (6,) on (x_j, x_{j+1}) into g and Hessian (6, 6) into H."""
    e0 = q[4 * j + 4] - q[4 * j]
    e1 = q[4 * j + 5] - q[4 * j + 1]
    e2 = q[4 * j + 6] - q[4 * j + 2]
    ln = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    u = (e0 / ln, e1 / ln, e2 / ln)
    strain = ln / rest - 1.0
    f = ks * strain
    for a in range(3):
        g[a] = -f * u[a]
        g[3 + a] = f * u[a]
    if hessian:
        for a in range(3):
            for b in range(3):
                uu = u[a] * u[b]
                he = ks * (uu / rest + (strain / ln) * ((1.0 if a == b else 0.0) - uu))
                H[a, b] = he
                H[3 + a, 3 + b] = he
                H[a, 3 + b] = -he
                H[3 + a, b] = -he
    return 0.5 * ks * rest * strain * strain


@njit(cache=True)
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def _skew(v, i, j):
    """Entry (i, j) of [v]_x."""
    if i == j:
        return 0.0
    if i == 0:
        return -v[2] if j == 1 else v[1]
    if i == 1:
        return v[2] if j == 0 else -v[0]
    return -v[1] if j == 0 else v[0]


@njit(cache=True)
def _place_positions(H, De2, Df2, DeDf, scale, add):
    """Position blocks of a stencil Hessian from the second derivatives in e = x_i - x_{i-1}, f = x_{i+1} - x_i
    (DfDe = DeDf^T): H[rows, cols] (+)= scale * block."""
    for a in range(3):
        for b in range(3):
            dee, dff, def_, dfe = De2[a, b], Df2[a, b], DeDf[a, b], DeDf[b, a]
            vals = (dee, -dee + def_, -def_,
                    -dee + dfe, dee - def_ - dfe + dff, def_ - dff,
                    -dfe, dfe - dff, dff)
            for r in range(3):
                for c in range(3):
                    v = scale * vals[3 * r + c]
                    if add:
                        H[4 * r + a, 4 * c + b] += v
                    else:
                        H[4 * r + a, 4 * c + b] = v


@njit(cache=True)
def _place_theta(H, row, Dth2, DeDth, DfDth, scale):
    """Row/column ``row`` (3 or 7, a twist angle) of a stencil Hessian: H += scale * (...)."""
    H[row, row] += scale * Dth2
    for a in range(3):
        v0, v1, v2 = -DeDth[a], DeDth[a] - DfDth[a], DfDth[a]
        H[row, a] += scale * v0
        H[row, 4 + a] += scale * v1
        H[row, 8 + a] += scale * v2
        H[a, row] += scale * v0
        H[4 + a, row] += scale * v1
        H[8 + a, row] += scale * v2


@njit(cache=True)
def _stencil_element(q, d1, d2, ref_twist, k, wb, wt, kr1, kr2, tau_rest, hessian, gb, gt, Hb, Ht, B):
    """Bending and twisting of interior node k + 1 (stencil q[4k : 4k + 11]); wb = EI / l, wt = GJ / l.

    Gradients (11,) into gb, gt; Hessians (11, 11) into Hb, Ht (B: (3, 3, 3) scratch). Returns (E_b, E_t)."""
    o = 4 * k
    ee = (q[o + 4] - q[o], q[o + 5] - q[o + 1], q[o + 6] - q[o + 2])
    ef = (q[o + 8] - q[o + 4], q[o + 9] - q[o + 5], q[o + 10] - q[o + 6])
    ne = np.sqrt(_dot(ee, ee))
    nf = np.sqrt(_dot(ef, ef))
    te = (ee[0] / ne, ee[1] / ne, ee[2] / ne)
    tf = (ef[0] / nf, ef[1] / nf, ef[2] / nf)
    ce, se = np.cos(q[o + 3]), np.sin(q[o + 3])
    cf, sf = np.cos(q[o + 7]), np.sin(q[o + 7])
    m1e = (ce * d1[k, 0] + se * d2[k, 0], ce * d1[k, 1] + se * d2[k, 1], ce * d1[k, 2] + se * d2[k, 2])
    m2e = (-se * d1[k, 0] + ce * d2[k, 0], -se * d1[k, 1] + ce * d2[k, 1], -se * d1[k, 2] + ce * d2[k, 2])
    m1f = (cf * d1[k + 1, 0] + sf * d2[k + 1, 0], cf * d1[k + 1, 1] + sf * d2[k + 1, 1],
           cf * d1[k + 1, 2] + sf * d2[k + 1, 2])
    m2f = (-sf * d1[k + 1, 0] + cf * d2[k + 1, 0], -sf * d1[k + 1, 1] + cf * d2[k + 1, 1],
           -sf * d1[k + 1, 2] + cf * d2[k + 1, 2])
    chi = 1.0 + _dot(te, tf)
    c = _cross(te, tf)
    kb = (2.0 * c[0] / chi, 2.0 * c[1] / chi, 2.0 * c[2] / chi)
    tt = ((te[0] + tf[0]) / chi, (te[1] + tf[1]) / chi, (te[2] + tf[2]) / chi)
    td1 = ((m1e[0] + m1f[0]) / chi, (m1e[1] + m1f[1]) / chi, (m1e[2] + m1f[2]) / chi)
    td2 = ((m2e[0] + m2f[0]) / chi, (m2e[1] + m2f[1]) / chi, (m2e[2] + m2f[2]) / chi)
    k1 = 0.5 * (kb[0] * (m2e[0] + m2f[0]) + kb[1] * (m2e[1] + m2f[1]) + kb[2] * (m2e[2] + m2f[2]))
    k2 = -0.5 * (kb[0] * (m1e[0] + m1f[0]) + kb[1] * (m1e[1] + m1f[1]) + kb[2] * (m1e[2] + m1f[2]))
    dk1, dk2 = k1 - kr1, k2 - kr2
    tau = q[o + 7] - q[o + 3] + ref_twist[k]
    dtau = tau - tau_rest
    # curvature gradients d kappa / d stencil (g1 into gb, g2 into gt for now)
    tf_td2, te_td2 = _cross(tf, td2), _cross(te, td2)
    tf_td1, te_td1 = _cross(tf, td1), _cross(te, td1)
    g1 = gb
    g2 = gt
    for a in range(3):
        Dk1De = (-k1 * tt[a] + tf_td2[a]) / ne
        Dk1Df = (-k1 * tt[a] - te_td2[a]) / nf
        Dk2De = (-k2 * tt[a] - tf_td1[a]) / ne
        Dk2Df = (-k2 * tt[a] + te_td1[a]) / nf
        g1[a], g1[4 + a], g1[8 + a] = -Dk1De, Dk1De - Dk1Df, Dk1Df
        g2[a], g2[4 + a], g2[8 + a] = -Dk2De, Dk2De - Dk2Df, Dk2Df
    g1[3] = -0.5 * _dot(kb, m1e)
    g1[7] = -0.5 * _dot(kb, m1f)
    g2[3] = -0.5 * _dot(kb, m2e)
    g2[7] = -0.5 * _dot(kb, m2f)
    if hessian:
        for i in range(11):
            for j in range(11):
                Hb[i, j] = wb * (g1[i] * g1[j] + g2[i] * g2[j])
        # kappa1's second derivatives, times dk1
        ne2, nf2, nenf = ne * ne, nf * nf, ne * nf
        for a in range(3):
            for b in range(3):
                d = 1.0 if a == b else 0.0
                ttab = tt[a] * tt[b]
                B[0, a, b] = ((2 * k1 * ttab - tf_td2[a] * tt[b] - tf_td2[b] * tt[a]) / ne2
                              - k1 / (chi * ne2) * (d - te[a] * te[b])
                              + (kb[a] * m2e[b] + kb[b] * m2e[a]) / (4 * ne2))
                B[1, a, b] = ((2 * k1 * ttab + te_td2[a] * tt[b] + te_td2[b] * tt[a]) / nf2
                              - k1 / (chi * nf2) * (d - tf[a] * tf[b])
                              + (kb[a] * m2f[b] + kb[b] * m2f[a]) / (4 * nf2))
                B[2, a, b] = (-k1 / (chi * nenf) * (d + te[a] * tf[b])
                              + (2 * k1 * ttab - tf_td2[a] * tt[b] + te_td2[b] * tt[a] - _skew(td2, a, b)) / nenf)
        _place_positions(Hb, B[0], B[1], B[2], wb * dk1, True)
        for a in range(3):
            for b in range(3):
                d = 1.0 if a == b else 0.0
                ttab = tt[a] * tt[b]
                B[0, a, b] = ((2 * k2 * ttab + tf_td1[a] * tt[b] + tf_td1[b] * tt[a]) / ne2
                              - k2 / (chi * ne2) * (d - te[a] * te[b])
                              - (kb[a] * m1e[b] + kb[b] * m1e[a]) / (4 * ne2))
                B[1, a, b] = ((2 * k2 * ttab - te_td1[a] * tt[b] - te_td1[b] * tt[a]) / nf2
                              - k2 / (chi * nf2) * (d - tf[a] * tf[b])
                              - (kb[a] * m1f[b] + kb[b] * m1f[a]) / (4 * nf2))
                B[2, a, b] = (-k2 / (chi * nenf) * (d + te[a] * tf[b])
                              + (2 * k2 * ttab + tf_td1[a] * tt[b] - te_td1[b] * tt[a] + _skew(td1, a, b)) / nenf)
        _place_positions(Hb, B[0], B[1], B[2], wb * dk2, True)
        # twist-angle rows: kappa1 and kappa2 (second derivatives in theta and mixed ones)
        kb_m1e, kb_m1f, kb_m2e, kb_m2f = _dot(kb, m1e), _dot(kb, m1f), _dot(kb, m2e), _dot(kb, m2f)
        tf_m1e, tf_m1f, te_m1e, te_m1f = _cross(tf, m1e), _cross(tf, m1f), _cross(te, m1e), _cross(te, m1f)
        tf_m2e, tf_m2f, te_m2e, te_m2f = _cross(tf, m2e), _cross(tf, m2f), _cross(te, m2e), _cross(te, m2f)
        for a in range(3):
            B[0, 0, a] = (0.5 * kb_m1e * tt[a] - tf_m1e[a] / chi) / ne     # D2k1 De Dthe
            B[0, 1, a] = (0.5 * kb_m1e * tt[a] + te_m1e[a] / chi) / nf     # D2k1 Df Dthe
            B[0, 2, a] = (0.5 * kb_m1f * tt[a] - tf_m1f[a] / chi) / ne     # D2k1 De Dthf
            B[1, 0, a] = (0.5 * kb_m1f * tt[a] + te_m1f[a] / chi) / nf     # D2k1 Df Dthf
            B[1, 1, a] = (0.5 * kb_m2e * tt[a] - tf_m2e[a] / chi) / ne     # D2k2 De Dthe
            B[1, 2, a] = (0.5 * kb_m2e * tt[a] + te_m2e[a] / chi) / nf     # D2k2 Df Dthe
            B[2, 0, a] = (0.5 * kb_m2f * tt[a] - tf_m2f[a] / chi) / ne     # D2k2 De Dthf
            B[2, 1, a] = (0.5 * kb_m2f * tt[a] + te_m2f[a] / chi) / nf     # D2k2 Df Dthf
        _place_theta(Hb, 3, -0.5 * kb_m2e, B[0, 0], B[0, 1], wb * dk1)
        _place_theta(Hb, 7, -0.5 * kb_m2f, B[0, 2], B[1, 0], wb * dk1)
        _place_theta(Hb, 3, 0.5 * kb_m1e, B[1, 1], B[1, 2], wb * dk2)
        _place_theta(Hb, 7, 0.5 * kb_m1f, B[2, 0], B[2, 1], wb * dk2)
    for i in range(11):
        gb[i] = wb * (dk1 * g1[i] + dk2 * g2[i])       # g1 is gb: the sum uses g1[i], g2[i] before they change
    # twisting: d tau / d stencil into gt
    for a in range(3):
        gt[a] = -0.5 * kb[a] / ne
        gt[8 + a] = 0.5 * kb[a] / nf
        gt[4 + a] = -(gt[a] + gt[8 + a])
    gt[3] = -1.0
    gt[7] = 1.0
    if hessian:
        for i in range(11):
            for j in range(11):
                Ht[i, j] = wt * gt[i] * gt[j]
        ne2, nf2, nenf = ne * ne, nf * nf, ne * nf
        for a in range(3):
            for b in range(3):
                aa, ab_ = te[a] + tt[a], te[b] + tt[b]
                ba, bb = tf[a] + tt[a], tf[b] + tt[b]
                B[0, a, b] = -0.25 / ne2 * (kb[a] * ab_ + aa * kb[b])
                B[1, a, b] = -0.25 / nf2 * (kb[a] * bb + ba * kb[b])
                B[2, a, b] = 0.5 / nenf * (2.0 / chi * _skew(te, a, b) - kb[a] * tt[b])
        _place_positions(Ht, B[0], B[1], B[2], wt * dtau, True)
    for i in range(11):
        gt[i] = wt * dtau * gt[i]
    return 0.5 * wb * (dk1 * dk1 + dk2 * dk2), 0.5 * wt * dtau * dtau


# ------------------------------------------------------------------------------------------------- loop kernels
@njit(cache=True)
def _stretching_blocks(q, rest, ks, hessian, grad, H):
    g = np.empty(6)
    E = 0.0
    for j in range(len(rest)):
        E += _stretch_element(q, j, rest[j], ks[j], hessian, g, H[j])
        for a in range(3):
            grad[4 * j + a] += g[a]
            grad[4 * j + 4 + a] += g[3 + a]
    return E


@njit(cache=True)
def _stencil_blocks(q, d1, d2, ref_twist, wb, wt, kappa_rest, tau_rest, hessian, grad_b, grad_t, Hb, Ht):
    gb, gt, B = np.empty(11), np.empty(11), np.empty((3, 3, 3))
    Eb = Et = 0.0
    for k in range(len(wb)):
        eb, et = _stencil_element(q, d1, d2, ref_twist, k, wb[k], wt[k], kappa_rest[k, 0], kappa_rest[k, 1],
                                  tau_rest[k], hessian, gb, gt, Hb[k], Ht[k], B)
        Eb += eb
        Et += et
        for i in range(11):
            grad_b[4 * k + i] += gb[i]
            grad_t[4 * k + i] += gt[i]
    return Eb, Et


# ---------------------------------------------------------------------------------------------- public functions
def _per_element(value, n):
    return np.ascontiguousarray(np.broadcast_to(np.asarray(value, float), (n,)))


def stretching(q, rest_lengths, ks, hessian=True):
    """Energy, gradient (4N+3) and Hessian blocks (N, 6, 6) on (x_j, x_{j+1}) of the stretching energy."""
    rest = np.ascontiguousarray(rest_lengths, float)
    grad = np.zeros(len(q))
    H = np.zeros((len(rest), 6, 6))
    E = _stretching_blocks(np.ascontiguousarray(q, float), rest, _per_element(ks, len(rest)), hessian, grad, H)
    return E, grad, (H if hessian else None)


def _stencils(q, d1, d2, ref_twist, voronoi_lengths, EI, GJ, kappa_rest, tau_rest, hessian):
    vor = np.asarray(voronoi_lengths, float)
    K = len(vor)
    kr = np.zeros((K, 2)) if kappa_rest is None else np.ascontiguousarray(kappa_rest, float)
    rt = np.zeros(K) if ref_twist is None else np.ascontiguousarray(ref_twist, float)
    grad_b, grad_t = np.zeros(len(q)), np.zeros(len(q))
    Hb, Ht = np.zeros((K, 11, 11)), np.zeros((K, 11, 11))
    Eb, Et = _stencil_blocks(np.ascontiguousarray(q, float), np.ascontiguousarray(d1, float),
                             np.ascontiguousarray(d2, float), rt, _per_element(EI, K) / vor,
                             _per_element(GJ, K) / vor, kr, _per_element(0.0 if tau_rest is None else tau_rest, K),
                             hessian, grad_b, grad_t, Hb, Ht)
    return (Eb, grad_b, Hb if hessian else None), (Et, grad_t, Ht if hessian else None)


def bending(q, d1, d2, voronoi_lengths, EI, kappa_rest=None, hessian=True):
    """Bending energy, gradient (4N+3) and stencil Hessians (N-1, 11, 11).

    d1, d2: reference frames (N, 3); kappa_rest: (N-1, 2) natural material curvatures (default straight).
    """
    return _stencils(q, d1, d2, None, voronoi_lengths, EI, 0.0, kappa_rest, None, hessian)[0]


def twisting(q, d1, d2, ref_twist, voronoi_lengths, GJ, twist_rest=None, hessian=True):
    """Twisting energy, gradient and stencil Hessians; ref_twist (N-1,) from ``reference_frames.reference_twist``."""
    return _stencils(q, d1, d2, ref_twist, voronoi_lengths, 0.0, GJ, None, twist_rest, hessian)[1]


@njit(cache=True)
def elastic_banded(q, d1, d2, ref_twist, rest, ks, wb, wt, kappa_rest, hessian, grad, ab):
    """Total elastic energy (stretching + bending + twisting, twist-free rest state) of q; its gradient is added to
    ``grad`` (4N+3) and, if ``hessian``, its Hessian to ``ab`` (LAPACK band storage, l = u = BAND: entry (i, j) at
    ab[BAND + i - j, j]). Per element: rest lengths and ks = EA (N,); wb = EI / l, wt = GJ / l, rest curvatures
    kappa_rest (N-1, 2) at the interior nodes (l: Voronoi length); reference frames d1, d2 (N, 3), twist (N-1,)."""
    g6, H6 = np.empty(6), np.empty((6, 6))
    E = 0.0
    for j in range(len(rest)):
        E += _stretch_element(q, j, rest[j], ks[j], hessian, g6, H6)
        for a in range(6):
            ia = 4 * j + a + (1 if a >= 3 else 0)
            grad[ia] += g6[a]
            if hessian:
                for b in range(6):
                    jb = 4 * j + b + (1 if b >= 3 else 0)
                    ab[BAND + ia - jb, jb] += H6[a, b]
    gb, gt, B = np.empty(11), np.empty(11), np.empty((3, 3, 3))
    Hb, Ht = np.empty((11, 11)), np.empty((11, 11))
    for k in range(len(wb)):
        eb, et = _stencil_element(q, d1, d2, ref_twist, k, wb[k], wt[k], kappa_rest[k, 0], kappa_rest[k, 1],
                                  0.0, hessian, gb, gt, Hb, Ht, B)
        E += eb + et
        o = 4 * k
        for i in range(11):
            grad[o + i] += gb[i] + gt[i]
            if hessian:
                for j in range(11):
                    ab[BAND + i - j, o + j] += Hb[i, j] + Ht[i, j]
    return E
