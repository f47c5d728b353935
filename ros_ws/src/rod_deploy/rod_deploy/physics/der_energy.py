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
"""
import numpy as np

from .reference_frames import material_frames


def _outer(a, b):
    return a[:, :, None] * b[:, None, :]


def _skew(v):
    z = np.zeros(v.shape[0])
    return np.stack([np.stack([z, -v[:, 2], v[:, 1]], -1),
                     np.stack([v[:, 2], z, -v[:, 0]], -1),
                     np.stack([-v[:, 1], v[:, 0], z], -1)], -2)


def _dot(a, b):
    return np.einsum('ki,ki->k', a, b)


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


# ----------------------------------------------------------------------------------------------------- stretching
def stretching(q, rest_lengths, ks, hessian=True):
    """Energy, gradient (4N+3) and Hessian blocks (N, 6, 6) on (x_j, x_{j+1}) of the stretching energy."""
    x = positions(q)
    e = np.diff(x, axis=0)
    ln = np.linalg.norm(e, axis=1)
    u = e / ln[:, None]
    ks = np.broadcast_to(np.asarray(ks, float), ln.shape)
    strain = ln / rest_lengths - 1.0
    energy = 0.5 * np.sum(ks * rest_lengths * strain ** 2)
    ge = (ks * strain)[:, None] * u                                   # dE/de
    grad = np.zeros_like(q)
    nd = node_dofs(len(x))
    np.add.at(grad, nd[1:], ge)
    np.add.at(grad, nd[:-1], -ge)
    if not hessian:
        return energy, grad, None
    eye = np.eye(3)[None]
    He = ks[:, None, None] * (_outer(u, u) / rest_lengths[:, None, None]
                              + (strain / ln)[:, None, None] * (eye - _outer(u, u)))
    H = np.zeros((len(ln), 6, 6))
    H[:, :3, :3] = He
    H[:, 3:, 3:] = He
    H[:, :3, 3:] = -He
    H[:, 3:, :3] = -He
    return energy, grad, H


def stretching_dofs(n_edges):
    """Global DOF indices (N, 6) of the stretching blocks."""
    nd = node_dofs(n_edges + 1)
    return np.concatenate([nd[:-1], nd[1:]], axis=1)


def stencil_dofs(n_edges):
    """Global DOF indices (N-1, 11) of the bending/twisting stencils."""
    return 4 * np.arange(n_edges - 1)[:, None] + np.arange(11)[None, :]


# ------------------------------------------------------------------------------------------- curvature, twist
class _Stencil:
    """Geometric quantities of the interior nodes."""

    def __init__(self, q, d1, d2):
        x = positions(q)
        th = thetas(q)
        e = np.diff(x, axis=0)
        ln = np.linalg.norm(e, axis=1)
        t = e / ln[:, None]
        m1, m2 = material_frames(d1, d2, th)
        self.ee, self.ef = e[:-1], e[1:]
        self.ne, self.nf = ln[:-1], ln[1:]
        self.te, self.tf = t[:-1], t[1:]
        self.d1e, self.d1f = m1[:-1], m1[1:]
        self.d2e, self.d2f = m2[:-1], m2[1:]
        self.chi = 1.0 + _dot(self.te, self.tf)
        self.kb = 2.0 * np.cross(self.te, self.tf) / self.chi[:, None]
        self.tt = (self.te + self.tf) / self.chi[:, None]
        self.td1 = (self.d1e + self.d1f) / self.chi[:, None]
        self.td2 = (self.d2e + self.d2f) / self.chi[:, None]
        self.kappa1 = 0.5 * _dot(self.kb, self.d2e + self.d2f)
        self.kappa2 = -0.5 * _dot(self.kb, self.d1e + self.d1f)


def curvature_gradients(S):
    """d kappa1 / d stencil and d kappa2 / d stencil, each (K, 11)."""
    K = len(S.kappa1)
    ne, nf = S.ne[:, None], S.nf[:, None]
    Dk1De = (-S.kappa1[:, None] * S.tt + np.cross(S.tf, S.td2)) / ne
    Dk1Df = (-S.kappa1[:, None] * S.tt - np.cross(S.te, S.td2)) / nf
    Dk2De = (-S.kappa2[:, None] * S.tt - np.cross(S.tf, S.td1)) / ne
    Dk2Df = (-S.kappa2[:, None] * S.tt + np.cross(S.te, S.td1)) / nf
    g1 = np.zeros((K, 11))
    g2 = np.zeros((K, 11))
    g1[:, 0:3], g1[:, 4:7], g1[:, 8:11] = -Dk1De, Dk1De - Dk1Df, Dk1Df
    g2[:, 0:3], g2[:, 4:7], g2[:, 8:11] = -Dk2De, Dk2De - Dk2Df, Dk2Df
    g1[:, 3] = -0.5 * _dot(S.kb, S.d1e)
    g1[:, 7] = -0.5 * _dot(S.kb, S.d1f)
    g2[:, 3] = -0.5 * _dot(S.kb, S.d2e)
    g2[:, 7] = -0.5 * _dot(S.kb, S.d2f)
    return g1, g2


def _assemble_stencil(DDe2, DDf2, DDeDf, DDfDe, Dthe2, Dthf2, DeDthe, DeDthf, DfDthe, DfDthf):
    K = DDe2.shape[0]
    H = np.zeros((K, 11, 11))
    H[:, 0:3, 0:3] = DDe2
    H[:, 0:3, 4:7] = -DDe2 + DDeDf
    H[:, 0:3, 8:11] = -DDeDf
    H[:, 4:7, 0:3] = -DDe2 + DDfDe
    H[:, 4:7, 4:7] = DDe2 - DDeDf - DDfDe + DDf2
    H[:, 4:7, 8:11] = DDeDf - DDf2
    H[:, 8:11, 0:3] = -DDfDe
    H[:, 8:11, 4:7] = DDfDe - DDf2
    H[:, 8:11, 8:11] = DDf2
    if Dthe2 is not None:
        H[:, 3, 3] = Dthe2
        H[:, 7, 7] = Dthf2
        H[:, 3, 0:3] = -DeDthe
        H[:, 3, 4:7] = DeDthe - DfDthe
        H[:, 3, 8:11] = DfDthe
        H[:, 7, 0:3] = -DeDthf
        H[:, 7, 4:7] = DeDthf - DfDthf
        H[:, 7, 8:11] = DfDthf
        H[:, 0:3, 3] = H[:, 3, 0:3]
        H[:, 4:7, 3] = H[:, 3, 4:7]
        H[:, 8:11, 3] = H[:, 3, 8:11]
        H[:, 0:3, 7] = H[:, 7, 0:3]
        H[:, 4:7, 7] = H[:, 7, 4:7]
        H[:, 8:11, 7] = H[:, 7, 8:11]
    return H


def curvature_hessians(S):
    """Second derivatives of kappa1 and kappa2 over the stencil, each (K, 11, 11)."""
    eye = np.eye(3)[None]
    ne, nf = S.ne[:, None, None], S.nf[:, None, None]
    ne2, nf2 = ne ** 2, nf ** 2
    chi = S.chi[:, None, None]
    k1 = S.kappa1[:, None, None]
    k2 = S.kappa2[:, None, None]
    tt_o_tt = _outer(S.tt, S.tt)
    te_o_te, tf_o_tf, te_o_tf = _outer(S.te, S.te), _outer(S.tf, S.tf), _outer(S.te, S.tf)

    # kappa1
    a = _outer(np.cross(S.tf, S.td2), S.tt)
    b = _outer(np.cross(S.te, S.td2), S.tt)
    kb_o_d2e, kb_o_d2f = _outer(S.kb, S.d2e), _outer(S.kb, S.d2f)
    D2k1De2 = (2 * k1 * tt_o_tt - a - a.transpose(0, 2, 1)) / ne2 - k1 / (chi * ne2) * (eye - te_o_te) \
        + (kb_o_d2e + kb_o_d2e.transpose(0, 2, 1)) / (4 * ne2)
    D2k1Df2 = (2 * k1 * tt_o_tt + b + b.transpose(0, 2, 1)) / nf2 - k1 / (chi * nf2) * (eye - tf_o_tf) \
        + (kb_o_d2f + kb_o_d2f.transpose(0, 2, 1)) / (4 * nf2)
    D2k1DeDf = -k1 / (chi * ne * nf) * (eye + te_o_tf) \
        + (2 * k1 * tt_o_tt - a + b.transpose(0, 2, 1) - _skew(S.td2)) / (ne * nf)
    D2k1DfDe = D2k1DeDf.transpose(0, 2, 1)

    # kappa2
    c = _outer(np.cross(S.tf, S.td1), S.tt)
    d = _outer(np.cross(S.te, S.td1), S.tt)
    kb_o_d1e, kb_o_d1f = _outer(S.kb, S.d1e), _outer(S.kb, S.d1f)
    D2k2De2 = (2 * k2 * tt_o_tt + c + c.transpose(0, 2, 1)) / ne2 - k2 / (chi * ne2) * (eye - te_o_te) \
        - (kb_o_d1e + kb_o_d1e.transpose(0, 2, 1)) / (4 * ne2)
    D2k2Df2 = (2 * k2 * tt_o_tt - d - d.transpose(0, 2, 1)) / nf2 - k2 / (chi * nf2) * (eye - tf_o_tf) \
        - (kb_o_d1f + kb_o_d1f.transpose(0, 2, 1)) / (4 * nf2)
    D2k2DeDf = -k2 / (chi * ne * nf) * (eye + te_o_tf) \
        + (2 * k2 * tt_o_tt + c - d.transpose(0, 2, 1) + _skew(S.td1)) / (ne * nf)
    D2k2DfDe = D2k2DeDf.transpose(0, 2, 1)

    # theta terms
    ne1, nf1, chi1 = S.ne[:, None], S.nf[:, None], S.chi[:, None]
    kb = S.kb
    D2k1Dthe2 = -0.5 * _dot(kb, S.d2e)
    D2k1Dthf2 = -0.5 * _dot(kb, S.d2f)
    D2k2Dthe2 = 0.5 * _dot(kb, S.d1e)
    D2k2Dthf2 = 0.5 * _dot(kb, S.d1f)
    D2k1DeDthe = (0.5 * _dot(kb, S.d1e)[:, None] * S.tt - np.cross(S.tf, S.d1e) / chi1) / ne1
    D2k1DeDthf = (0.5 * _dot(kb, S.d1f)[:, None] * S.tt - np.cross(S.tf, S.d1f) / chi1) / ne1
    D2k1DfDthe = (0.5 * _dot(kb, S.d1e)[:, None] * S.tt + np.cross(S.te, S.d1e) / chi1) / nf1
    D2k1DfDthf = (0.5 * _dot(kb, S.d1f)[:, None] * S.tt + np.cross(S.te, S.d1f) / chi1) / nf1
    D2k2DeDthe = (0.5 * _dot(kb, S.d2e)[:, None] * S.tt - np.cross(S.tf, S.d2e) / chi1) / ne1
    D2k2DeDthf = (0.5 * _dot(kb, S.d2f)[:, None] * S.tt - np.cross(S.tf, S.d2f) / chi1) / ne1
    D2k2DfDthe = (0.5 * _dot(kb, S.d2e)[:, None] * S.tt + np.cross(S.te, S.d2e) / chi1) / nf1
    D2k2DfDthf = (0.5 * _dot(kb, S.d2f)[:, None] * S.tt + np.cross(S.te, S.d2f) / chi1) / nf1

    H1 = _assemble_stencil(D2k1De2, D2k1Df2, D2k1DeDf, D2k1DfDe, D2k1Dthe2, D2k1Dthf2,
                           D2k1DeDthe, D2k1DeDthf, D2k1DfDthe, D2k1DfDthf)
    H2 = _assemble_stencil(D2k2De2, D2k2Df2, D2k2DeDf, D2k2DfDe, D2k2Dthe2, D2k2Dthf2,
                           D2k2DeDthe, D2k2DeDthf, D2k2DfDthe, D2k2DfDthf)
    return H1, H2


def bending(q, d1, d2, voronoi_lengths, EI, kappa_rest=None, hessian=True):
    """Bending energy, gradient (4N+3) and stencil Hessians (N-1, 11, 11).

    d1, d2: reference frames (N, 3); kappa_rest: (N-1, 2) natural material curvatures (default straight).
    """
    S = _Stencil(q, d1, d2)
    k = np.stack([S.kappa1, S.kappa2], axis=1)
    dk = k if kappa_rest is None else k - kappa_rest
    EI = np.broadcast_to(np.asarray(EI, float), (len(dk),))
    w = EI / voronoi_lengths
    energy = 0.5 * np.sum(w * np.sum(dk ** 2, axis=1))
    g1, g2 = curvature_gradients(S)
    gl = w[:, None] * (dk[:, :1] * g1 + dk[:, 1:] * g2)
    grad = np.zeros_like(q)
    np.add.at(grad, stencil_dofs(len(dk) + 1), gl)
    if not hessian:
        return energy, grad, None
    H1, H2 = curvature_hessians(S)
    H = w[:, None, None] * (_outer(g1, g1) + _outer(g2, g2) + dk[:, 0, None, None] * H1 + dk[:, 1, None, None] * H2)
    return energy, grad, H


def twisting(q, d1, d2, ref_twist, voronoi_lengths, GJ, twist_rest=None, hessian=True):
    """Twisting energy, gradient and stencil Hessians; ref_twist (N-1,) from ``reference_frames.reference_twist``."""
    x = positions(q)
    th = thetas(q)
    e = np.diff(x, axis=0)
    ln = np.linalg.norm(e, axis=1)
    t = e / ln[:, None]
    te, tf, ne, nf = t[:-1], t[1:], ln[:-1], ln[1:]
    chi = 1.0 + _dot(te, tf)
    kb = 2.0 * np.cross(te, tf) / chi[:, None]
    tau = th[1:] - th[:-1] + ref_twist
    dtau = tau if twist_rest is None else tau - twist_rest
    GJ = np.broadcast_to(np.asarray(GJ, float), tau.shape)
    w = GJ / voronoi_lengths
    energy = 0.5 * np.sum(w * dtau ** 2)
    K = len(tau)
    g = np.zeros((K, 11))
    g[:, 0:3] = -0.5 * kb / ne[:, None]
    g[:, 8:11] = 0.5 * kb / nf[:, None]
    g[:, 4:7] = -(g[:, 0:3] + g[:, 8:11])
    g[:, 3] = -1.0
    g[:, 7] = 1.0
    grad = np.zeros_like(q)
    np.add.at(grad, stencil_dofs(K + 1), (w * dtau)[:, None] * g)
    if not hessian:
        return energy, grad, None
    tt = (te + tf) / chi[:, None]
    ne2, nf2 = (ne ** 2)[:, None, None], (nf ** 2)[:, None, None]
    a, b = te + tt, tf + tt
    D2mDe2 = -0.25 / ne2 * (_outer(kb, a) + _outer(a, kb))
    D2mDf2 = -0.25 / nf2 * (_outer(kb, b) + _outer(b, kb))
    D2mDeDf = 0.5 / (ne * nf)[:, None, None] * (2.0 / chi[:, None, None] * _skew(te) - _outer(kb, tt))
    D2mDfDe = D2mDeDf.transpose(0, 2, 1)
    DD = _assemble_stencil(D2mDe2, D2mDf2, D2mDeDf, D2mDfDe, None, None, None, None, None, None)
    H = w[:, None, None] * (_outer(g, g) + dtau[:, None, None] * DD)
    return energy, grad, H
