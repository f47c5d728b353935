"""Reference and material frames of discrete elastic rods (Bergou et al. 2008, 2010; paper Sec. 3.1).

Each edge e^i = x_{i+1} - x_i carries an adapted reference frame (d1^i, d2^i, t^i), updated between time steps by
*time-parallel transport* (rotate the old frame with the rotation that takes the old tangent to the new one), and a
material frame (m1^i, m2^i, t^i) obtained by rotating the reference frame by the twist angle theta^i about t^i.
The *reference twist* of interior node i is the angle between d1^i and the space-parallel transport of d1^{i-1}.

All functions are vectorised over edges/nodes (leading axis).
"""
import numpy as np


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def parallel_transport(u, t1, t2):
    """Transport vectors u (..., 3) from unit tangents t1 to t2 by the minimal rotation about t1 x t2."""
    b = np.cross(t1, t2)
    nb = np.linalg.norm(b, axis=-1, keepdims=True)
    c = np.sum(t1 * t2, axis=-1, keepdims=True)
    out = np.array(u, dtype=float, copy=True)
    mask = nb[..., 0] > 1e-15
    if np.any(mask):
        bb = b[mask] / nb[mask]
        uu = u[mask]
        cc, ss = c[mask], nb[mask]
        # Rodrigues rotation by angle atan2(|b|, c) about bb
        out[mask] = (uu * cc + np.cross(bb, uu) * ss + bb * np.sum(bb * uu, axis=-1, keepdims=True) * (1 - cc))
    return out


def edge_tangents(x):
    """Unit tangents (N, 3) and lengths (N,) of the edges of a node array x (N+1, 3)."""
    e = np.diff(x, axis=0)
    ln = np.linalg.norm(e, axis=1)
    return e / ln[:, None], ln


def initial_reference_frames(x, d1_first=None):
    """Space-parallel reference frames along the rod; d1 of edge 0 is d1_first or any normal to t^0."""
    t, _ = edge_tangents(x)
    d1 = np.zeros_like(t)
    if d1_first is None:
        a = np.array([0.0, 0.0, 1.0]) if abs(t[0, 2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        d1_first = np.cross(t[0], a)
    v = np.asarray(d1_first, float)
    v = v - t[0] * np.dot(v, t[0])
    d1[0] = v / np.linalg.norm(v)
    for i in range(1, len(t)):
        d = parallel_transport(d1[i - 1][None], t[i - 1][None], t[i][None])[0]
        d = d - t[i] * np.dot(d, t[i])
        d1[i] = d / np.linalg.norm(d)
    d2 = np.cross(t, d1)
    return d1, d2


def time_parallel_transport(d1_old, t_old, t_new):
    """Update reference frames between configurations: d1 follows its tangent by parallel transport."""
    d1 = parallel_transport(d1_old, t_old, t_new)
    d1 = d1 - t_new * np.sum(d1 * t_new, axis=1, keepdims=True)
    d1 = _unit(d1)
    return d1, np.cross(t_new, d1)


def signed_angle(u, v, n):
    """Angle from u to v about axis n (all (..., 3))."""
    w = np.cross(u, v)
    return np.arctan2(np.sum(w * n, axis=-1), np.sum(u * v, axis=-1))


def reference_twist(d1, t, ref_twist_old=None):
    """Reference twist at interior nodes 1..N-1: angle of d1^i relative to the space-parallel transport of d1^{i-1}.

    ref_twist_old (optional) removes 2 pi jumps so the twist is continuous in time.
    """
    u = parallel_transport(d1[:-1], t[:-1], t[1:])
    tw = signed_angle(u, d1[1:], t[1:])
    if ref_twist_old is not None:
        tw = tw + 2 * np.pi * np.round((ref_twist_old - tw) / (2 * np.pi))
    return tw


def material_frames(d1, d2, theta):
    """m1 = cos(theta) d1 + sin(theta) d2, m2 = -sin(theta) d1 + cos(theta) d2."""
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    return c * d1 + s * d2, -s * d1 + c * d2
