"""Reference and material frames of discrete elastic rods (Bergou et al. 2008, 2010; paper Sec. 3.1).

Each edge e^i = x_{i+1} - x_i carries an adapted reference frame (d1^i, d2^i, t^i), updated between time steps by
*time-parallel transport* (rotate the old frame with the rotation that takes the old tangent to the new one), and a
material frame (m1^i, m2^i, t^i) obtained by rotating the reference frame by the twist angle theta^i about t^i.
The *reference twist* of interior node i is the angle between d1^i and the space-parallel transport of d1^{i-1}.

All functions are vectorised over edges/nodes (leading axis).
"""
import numpy as np
from numba import njit


@njit(cache=True)
def _transport_row(u, t1, t2, out):
    """out = u rotated by the minimal rotation taking unit t1 to unit t2 (Rodrigues, angle atan2(|b|, c) about
    b = t1 x t2); u unchanged when t1 and t2 are parallel."""
    b0, b1, b2 = t1[1] * t2[2] - t1[2] * t2[1], t1[2] * t2[0] - t1[0] * t2[2], t1[0] * t2[1] - t1[1] * t2[0]
    nb = np.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
    if not nb > 1e-15:
        out[0], out[1], out[2] = u[0], u[1], u[2]
        return
    c = t1[0] * t2[0] + t1[1] * t2[1] + t1[2] * t2[2]
    b0, b1, b2 = b0 / nb, b1 / nb, b2 / nb
    bu = b0 * u[0] + b1 * u[1] + b2 * u[2]
    x0, x1, x2 = b1 * u[2] - b2 * u[1], b2 * u[0] - b0 * u[2], b0 * u[1] - b1 * u[0]
    out[0] = u[0] * c + x0 * nb + b0 * bu * (1 - c)
    out[1] = u[1] * c + x1 * nb + b1 * bu * (1 - c)
    out[2] = u[2] * c + x2 * nb + b2 * bu * (1 - c)


@njit(cache=True)
def _transport_rows(u, t1, t2, out):
    for i in range(u.shape[0]):
        _transport_row(u[i], t1[i], t2[i], out[i])


def parallel_transport(u, t1, t2):
    """Transport vectors u (..., 3) from unit tangents t1 to t2 by the minimal rotation about t1 x t2."""
    u, t1, t2 = np.broadcast_arrays(np.asarray(u, float), np.asarray(t1, float), np.asarray(t2, float))
    shape = u.shape
    flat = [np.ascontiguousarray(a.reshape(-1, 3)) for a in (u, t1, t2)]
    out = np.empty_like(flat[0])
    _transport_rows(*flat, out)
    return out.reshape(shape)


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


@njit(cache=True)
def _signed_angle(u, v, n):
    w0, w1, w2 = u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]
    return np.arctan2(w0 * n[0] + w1 * n[1] + w2 * n[2], u[0] * v[0] + u[1] * v[1] + u[2] * v[2])


@njit(cache=True)
def _time_parallel_transport(d1_old, t_old, t_new, d1, d2):
    for i in range(t_new.shape[0]):
        _transport_row(d1_old[i], t_old[i], t_new[i], d1[i])
        t = t_new[i]
        p = d1[i, 0] * t[0] + d1[i, 1] * t[1] + d1[i, 2] * t[2]
        a0, a1, a2 = d1[i, 0] - t[0] * p, d1[i, 1] - t[1] * p, d1[i, 2] - t[2] * p
        n = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        d1[i, 0], d1[i, 1], d1[i, 2] = a0 / n, a1 / n, a2 / n
        d2[i, 0] = t[1] * d1[i, 2] - t[2] * d1[i, 1]
        d2[i, 1] = t[2] * d1[i, 0] - t[0] * d1[i, 2]
        d2[i, 2] = t[0] * d1[i, 1] - t[1] * d1[i, 0]


@njit(cache=True)
def _reference_twist(d1, t, ref_twist_old, continuous, out):
    u = np.empty(3)
    for i in range(t.shape[0] - 1):
        _transport_row(d1[i], t[i], t[i + 1], u)
        tw = _signed_angle(u, d1[i + 1], t[i + 1])
        if continuous:
            tw = tw + 2 * np.pi * np.rint((ref_twist_old[i] - tw) / (2 * np.pi))
        out[i] = tw


@njit(cache=True)
def transported_frames(q, d1_old, t_old, ref_twist_old):
    """The frames of configuration q (DOF vector of ``der_energy``) carried from the previous ones: unit tangents,
    d1, d2 by time-parallel transport, and the reference twist made continuous with ``ref_twist_old``."""
    n_edges = (len(q) - 3) // 4
    t = np.empty((n_edges, 3))
    for j in range(n_edges):
        e0, e1, e2 = q[4 * j + 4] - q[4 * j], q[4 * j + 5] - q[4 * j + 1], q[4 * j + 6] - q[4 * j + 2]
        ln = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        t[j, 0], t[j, 1], t[j, 2] = e0 / ln, e1 / ln, e2 / ln
    d1, d2 = np.empty((n_edges, 3)), np.empty((n_edges, 3))
    _time_parallel_transport(d1_old, t_old, t, d1, d2)
    rt = np.empty(n_edges - 1)
    _reference_twist(d1, t, ref_twist_old, True, rt)
    return d1, d2, t, rt


def time_parallel_transport(d1_old, t_old, t_new):
    """Update reference frames between configurations: d1 follows its tangent by parallel transport."""
    t_new = np.ascontiguousarray(t_new, float)
    d1, d2 = np.empty_like(t_new), np.empty_like(t_new)
    _time_parallel_transport(np.ascontiguousarray(d1_old, float), np.ascontiguousarray(t_old, float), t_new, d1, d2)
    return d1, d2


@njit(cache=True)
def _signed_angles(u, v, n, out):
    for i in range(u.shape[0]):
        out[i] = _signed_angle(u[i], v[i], n[i])


def signed_angle(u, v, n):
    """Angle from u to v about axis n (all (..., 3))."""
    u, v, n = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float), np.asarray(n, float))
    flat = [np.ascontiguousarray(a.reshape(-1, 3)) for a in (u, v, n)]
    out = np.empty(len(flat[0]))
    _signed_angles(*flat, out)
    return out.reshape(u.shape[:-1]) if u.ndim > 1 else out[0]


def reference_twist(d1, t, ref_twist_old=None):
    """Reference twist at interior nodes 1..N-1: angle of d1^i relative to the space-parallel transport of d1^{i-1}.

    ref_twist_old (optional) removes 2 pi jumps so the twist is continuous in time.
    """
    t = np.ascontiguousarray(t, float)
    out = np.empty(len(t) - 1)
    old = out if ref_twist_old is None else np.ascontiguousarray(ref_twist_old, float)
    _reference_twist(np.ascontiguousarray(d1, float), t, old, ref_twist_old is not None, out)
    return out


def material_frames(d1, d2, theta):
    """m1 = cos(theta) d1 + sin(theta) d2, m2 = -sin(theta) d1 + cos(theta) d2."""
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    return c * d1 + s * d2, -s * d1 + c * d2
