"""Sub-pixel centreline: edge-centred refinement, smoothing, end placement and arc-length resampling.

A skeleton is a chain of pixel centres, up to half a pixel off the true centre line and shortened or
lengthened at the ends. For each point of a traced path the foreground evidence is sampled (bilinearly)
across the path, the two edges (steepest change of evidence, found to sub-pixel precision) are located,
and the point moves to their midpoint; the distance between them is the local width. Where the rod's
colour stands out from the table's, the edges are looked for in the rod's share of the light instead
(:func:`rod_share_profiles`; on a table within a factor 2 of the rod's brightness): the evidence |I - B| of a round
rod's shaded flank can be as low as the table's (the steepest change was then the shading inside the rod,
and the path sat 1-2.5 px towards the lit flank) and that of its shadow beside it as high as the rod's.
Points in crossings, where a second strand corrupts the profile, and points whose width is implausible
keep their skeleton position (their correction is interpolated from the neighbours). The path is then
smoothed along its arc length by a Gaussian (odd reflection at open ends keeps the ends and their
tangents). Each open end loses its last 0.6 widths (thinning bends them towards a corner of a flat end)
and is extended along the tangent of the stretch before to one half-width inside the object's boundary,
i.e. to the centre of a round pen tip or of a round-capped rod end; an end that runs off the image stops
at the image border. Units: pixels, points (row, col).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit
from scipy.ndimage import gaussian_filter1d

from rod_deploy.perception.crossing_order import _pairwise_sum
from rod_deploy.perception.fma import fma32


@dataclass
class RefinedPath:
    points: np.ndarray          # (n, 2) (row, col) [px]
    width_px: float             # median measured width (nan if never measured)
    closed: bool
    widths: np.ndarray          # measured width [px] per point of refine()'s output (nan: not measured);
                                # place_ends() keeps it as is


def arc_length(points: np.ndarray) -> np.ndarray:
    """Cumulative arc length [px] along (n, 2) points (0 at the first)."""
    if len(points) < 2:
        return np.zeros(len(points))
    points = np.asarray(points)
    if points.dtype == np.float64 and points.ndim == 2 and points.shape[1] == 2:
        return _arc_length(points)
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])


@njit(cache=True, nogil=True)
def _arc_length(points):
    """np.concatenate([[0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))]), the same sums in the same order."""
    s = np.empty(points.shape[0])
    s[0] = 0.0
    for i in range(1, points.shape[0]):
        step = np.hypot(points[i, 0] - points[i - 1, 0], points[i, 1] - points[i - 1, 1])
        s[i] = step if i == 1 else s[i - 1] + step
    return s


def path_length(points: np.ndarray) -> float:
    """Length [px] of the polyline through (n, 2) ``points``: ``np.sum(np.hypot(*np.diff(points, axis=0).T))``,
    the same pairwise sum, compiled."""
    points = np.asarray(points)
    if len(points) < 2:
        return 0.0
    if points.dtype == np.float64 and points.ndim == 2 and points.shape[1] == 2:
        return float(_path_length(points))
    return float(np.sum(np.hypot(*np.diff(points, axis=0).T)))


@njit(cache=True, nogil=True)
def _path_length(points):
    steps = np.empty(points.shape[0] - 1)
    for i in range(steps.size):
        steps[i] = np.hypot(points[i + 1, 0] - points[i, 0], points[i + 1, 1] - points[i, 1])
    return _pairwise_sum(steps, 0, steps.size)


def lookup(image, points):
    """``image`` at the pixels nearest to (row, col) ``points`` (rounded half to even, as np.round; clipped
    to the image), compiled for float point arrays."""
    points = np.asarray(points)
    if points.dtype != np.float64 or points.ndim != 2 or image.ndim != 2:
        p = np.round(points).astype(int)
        return image[np.minimum(np.maximum(p[:, 0], 0), image.shape[0] - 1),
                     np.minimum(np.maximum(p[:, 1], 0), image.shape[1] - 1)]
    out = np.empty(len(points), image.dtype)
    _lookup_kernel(image.view(np.uint8) if image.dtype == bool else image, points,
                   out.view(np.uint8) if image.dtype == bool else out)
    return out


@njit(cache=True, nogil=True)
def _lookup_kernel(image, points, out):
    h, w = image.shape
    for i in range(points.shape[0]):
        out[i] = image[min(max(int(np.rint(points[i, 0])), 0), h - 1), min(max(int(np.rint(points[i, 1])), 0), w - 1)]


def resample(points: np.ndarray, step_px: float) -> np.ndarray:
    """Points at equal arc-length spacing (last spacing at most ``step_px``), both ends kept (repeated points,
    less than 1e-9 px on from the one before, dropped first); compiled (:func:`_resample`)."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2 or not len(points):
        raise ValueError(f'expected (n >= 1, 2) points (row, col), got shape {points.shape}')
    return _resample(np.ascontiguousarray(points), float(step_px))


@njit(cache=True, nogil=True)
def _resample(points, step_px):
    """:func:`resample` of (n >= 1, 2) float64 points: the numpy formulas' arithmetic (arc length as
    :func:`_arc_length`; a point kept where np.diff of it exceeds 1e-9; n = max(2, ceil(s[-1] / step) + 1) points
    by :func:`_resample_at`; a single point, or no length, gives the first point)."""
    s = _arc_length(points)
    kept = np.empty(points.shape)
    s_kept = np.empty(s.size)
    m = 0
    for i in range(s.size):
        if i == 0 or s[i] - s[i - 1] > 1e-9:
            kept[m, 0], kept[m, 1] = points[i, 0], points[i, 1]
            s_kept[m] = s[i]
            m += 1
    if m < 2 or s_kept[m - 1] <= 0:
        return kept[:1].copy()
    n = max(2, int(np.ceil(s_kept[m - 1] / step_px)) + 1)
    return _resample_at(kept[:m], s_kept[:m], n)


@njit(cache=True, nogil=True)
def _resample_at(points, s, n):
    """The (n, 2) points at arc lengths np.linspace(0, s[-1], n) along ``points`` (arc lengths ``s``, strictly
    increasing): numpy's linspace and np.interp arithmetic (t_k = k step + 0, the last exactly s[-1]; between
    s_j <= t < s_j+1: slope (t - s_j) + y_j with slope = (y_j+1 - y_j) / (s_j+1 - s_j); at a sample: y_j)."""
    m = s.size
    out = np.empty((n, 2))
    step = (s[m - 1] - 0.0) / (n - 1)
    j = 0
    for k in range(n):
        t = k * step + 0.0 if k < n - 1 else s[m - 1]
        while j < m - 1 and s[j + 1] <= t:
            j += 1
        for c in range(2):
            if j == m - 1 or s[j] == t:
                out[k, c] = points[j, c]
            else:
                slope = (points[j + 1, c] - points[j, c]) / (s[j + 1] - s[j])
                out[k, c] = slope * (t - s[j]) + points[j, c]
    return out


def smooth(points: np.ndarray, sigma_pts: float, closed: bool) -> np.ndarray:
    """Gaussian smoothing along the point index (points at ~equal spacing). Open paths use odd (point)
    reflection at the ends, which keeps the end points and straight end tangents unbiased. (n, 2) points,
    float64 out (:func:`_smooth_path`, compiled)."""
    points = _as_path(points)
    if sigma_pts <= 0 or len(points) < 3:
        return points.copy()
    pad = 0 if closed else min(len(points) - 1, int(np.ceil(4 * sigma_pts)))
    return _smooth_path(points, _gaussian_weights(float(sigma_pts)), closed, pad)


@njit(cache=True, nogil=True)
def _smooth_path(points, weights, closed, pad):
    """:func:`smooth` of (n, 2) float64 points: closed, the body (without the repeated last point) filtered
    with periodic ends and its first point appended; open, extended by ``pad`` points reflected through
    each end (2 p_0 - p_k, 2 p_n-1 - p_n-1-k), filtered (ends extended with the end sample) and cut back."""
    n = points.shape[0]
    if closed:
        out = np.empty((n, 2))
        out[:n - 1] = _symmetric_correlate(points[:n - 1], weights, True)
        out[n - 1] = out[0]
        return out
    ext = np.empty((n + 2 * pad, 2))
    for k in range(pad):
        for c in range(2):
            ext[k, c] = 2 * points[0, c] - points[pad - k, c]
            ext[n + pad + k, c] = 2 * points[n - 1, c] - points[n - 2 - k, c]
    ext[pad:pad + n] = points
    return _symmetric_correlate(ext, weights, False)[pad:pad + n].copy()


def gaussian_filter(values: np.ndarray, sigma: float, wrap: bool) -> np.ndarray:
    """``scipy.ndimage.gaussian_filter1d(values, sigma, axis=0, mode='wrap' if wrap else 'nearest')``, the same
    numbers bit for bit (the same kernel, truncated at 4 sigma, and the same order of the sums, pairs of
    samples symmetric about the centre first), compiled: on the short paths here scipy's per-call
    overhead was most of the cost. Non-float64 input goes to scipy."""
    values = np.asarray(values)
    if values.dtype != np.float64 or values.ndim not in (1, 2) or not len(values):
        return gaussian_filter1d(values, sigma, axis=0, mode='wrap' if wrap else 'nearest')
    columns = values.reshape(len(values), -1)
    return _symmetric_correlate(columns, _gaussian_weights(float(sigma)), wrap).reshape(values.shape)


@lru_cache(maxsize=16)
def _gaussian_weights(sigma: float) -> np.ndarray:
    """The normalised Gaussian kernel, radius int(4 sigma + 0.5) samples."""
    radius = int(4.0 * sigma + 0.5)
    x = np.arange(-radius, radius + 1)
    phi = np.exp(-0.5 / (sigma * sigma) * x ** 2)
    return (phi / phi.sum())[::-1].copy()


@njit(cache=True, nogil=True)
def _symmetric_correlate(x, weights, wrap):
    """Each column of ``x`` correlated with the symmetric ``weights``, the ends extended periodically
    (``wrap``) or with the end sample: out_i = x_i w_0 + sum_{j = r..1} (x_{i-j} + x_{i+j}) w_j, in that order."""
    n, m = x.shape
    r = (weights.size - 1) // 2
    out = np.empty((n, m))
    ext = np.empty(n + 2 * r)
    for c in range(m):
        for i in range(n + 2 * r):
            k = i - r
            k = k % n if wrap else min(max(k, 0), n - 1)
            ext[i] = x[k, c]
        for i in range(n):
            p = i + r
            acc = ext[p] * weights[r]
            for j in range(-r, 0):
                acc += (ext[p + j] + ext[p - j]) * weights[r + j]
            out[i, c] = acc
    return out


def tangents(points: np.ndarray, closed: bool) -> np.ndarray:
    """Unit tangents of an (n, 2) path (:func:`_unit_tangents`: central differences as np.gradient, round
    the loop if ``closed``; zero where the differences vanish)."""
    points = _as_path(points)
    if len(points) < 2:
        return np.tile([0.0, 1.0], (len(points), 1))
    return _unit_tangents(points, closed)


def _as_path(points) -> np.ndarray:
    """(n, 2) float64 C-contiguous points, or a ValueError."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f'expected (n, 2) points (row, col), got shape {points.shape}')
    return points


@njit(cache=True, nogil=True)
def _unit_tangents(points, closed):
    """:func:`tangents` of (n >= 2, 2) float64 points: closed, p_k+1 - p_k-1 round the body (the last point
    repeats the first); open, np.gradient's (p_k+1 - p_k-1) / 2 inside and one-sided differences at the ends;
    each divided by its length sqrt(x^2 + y^2) (np.linalg.norm), 1 where that is 0."""
    n = points.shape[0]
    t = np.empty((n, 2))
    if closed:
        m = n - 1
        for k in range(m):
            for c in range(2):
                t[k, c] = points[(k + 1) % m, c] - points[(k - 1) % m, c]
        t[m] = t[0]
    else:
        for c in range(2):
            t[0, c] = (points[1, c] - points[0, c]) / 1.0
            t[n - 1, c] = (points[n - 1, c] - points[n - 2, c]) / 1.0
            for k in range(1, n - 1):
                t[k, c] = (points[k + 1, c] - points[k - 1, c]) / 2.0
    for k in range(n):
        norm = np.sqrt(t[k, 0] * t[k, 0] + t[k, 1] * t[k, 1])
        if norm == 0:
            norm = 1.0
        t[k, 0] /= norm
        t[k, 1] /= norm
    return t


def profile_offsets(half_span_px: float, step_px: float = 0.5) -> np.ndarray:
    """The offsets [px] along the normal at which :func:`edge_profiles` and :func:`rod_share_profiles` sample."""
    return np.arange(-half_span_px, half_span_px + 1e-9, step_px)


def edge_profiles(evidence: np.ndarray, points: np.ndarray, normals: np.ndarray, half_span_px: float,
                  step_px: float = 0.5):
    """Evidence (a one-channel uint8 or float32 image) sampled across the path: float32 (n, k) profiles at
    offsets (k,) [px] along the normals; bilinear, border replicated, the numbers of ``cv2.remap`` of the image
    as float32 (:func:`_bilinear`; compiled, so neither a float32 copy of the image nor sample maps are made)."""
    offsets = profile_offsets(half_span_px, step_px)
    prof = _profiles(evidence, np.ascontiguousarray(points, dtype=np.float64),
                     np.ascontiguousarray(normals, dtype=np.float64), offsets)
    return prof, offsets


@njit(cache=True, nogil=True)
def _profiles(evidence, points, normals, offsets):
    """out[i, j] = :func:`_bilinear` of ``evidence`` at p_i + o_j n_i (computed in float64, then rounded to
    float32, as numpy does with points[:, k:k+1] + offsets[None, :] * normals[:, k:k+1] and remap reads it)."""
    n, k = points.shape[0], offsets.size
    out = np.empty((n, k), np.float32)
    for i in range(n):
        for j in range(k):
            out[i, j] = _bilinear(evidence, np.float32(points[i, 0] + offsets[j] * normals[i, 0]),
                                  np.float32(points[i, 1] + offsets[j] * normals[i, 1]))
    return out


@njit(cache=True, nogil=True)
def _bilinear(image, r, c):
    """The value at float32 (row, col) of a one-channel image, as ``cv2.remap(image.astype(np.float32), ...,
    INTER_LINEAR, borderMode=BORDER_REPLICATE)`` gives it (OpenCV's remap kernel: neighbours at the floor
    and the floor + 1, clamped to the image; fractions a_c = c - floor(c), a_r likewise; v_0 = fma(a_c,
    p01 - p00, p00), v_1 = fma(a_c, p11 - p10, p10), then fma(a_r, v_1 - v_0, v_0), all in float32; bit for bit,
    checked against cv2.remap in the tests)."""
    h, w = image.shape
    rf, cf = np.floor(r), np.floor(c)
    ar, ac = r - rf, c - cf
    r0, c0 = int(rf), int(cf)
    if r0 >= 0 and c0 >= 0 and r0 < h - 1 and c0 < w - 1:      # inside: no clamping needed (most samples)
        p00, p01 = np.float32(image[r0, c0]), np.float32(image[r0, c0 + 1])
        p10, p11 = np.float32(image[r0 + 1, c0]), np.float32(image[r0 + 1, c0 + 1])
    else:
        ra, rb = min(max(r0, 0), h - 1), min(max(r0 + 1, 0), h - 1)
        ca, cb = min(max(c0, 0), w - 1), min(max(c0 + 1, 0), w - 1)
        p00, p01 = np.float32(image[ra, ca]), np.float32(image[ra, cb])
        p10, p11 = np.float32(image[rb, ca]), np.float32(image[rb, cb])
    v0 = fma32(ac, p01 - p00, p00)
    v1 = fma32(ac, p11 - p10, p10)
    return fma32(ar, v1 - v0, v0)


@njit(cache=True, nogil=True)
def _end_target(evidence, end, t, steps, floor, half_width_px):
    """(found, target): where the end at ``end`` (row, col) should go along the unit tangent ``t``, as an
    offset [px] along it. The evidence is sampled (:func:`_bilinear`) at ``end + steps t``; the boundary's
    foot is the first sample inside the image (the ray may enter it late) below 35 % of the peak (the
    largest of the first 8 samples; the level at least ``floor``): where the first sample is already
    below 15 % (at least ``floor`` / 2), the end is outside (target 0); else the steepest fall (central
    differences) from one step before the first sample below 60 % of the peak (at least ``floor``) to
    one step past the foot, refined by a parabola, and the target is half a width inside it (the search
    stops at 35 %, not lower: a rod's shadow beyond its end can hold the evidence above 15 % past the
    ray's reach, and its own edge can be as steep as the rod's). No foot but the ray leaves the image:
    the step before the first sample outside it. Neither: not found. Float32 samples compared with float32 levels, as numpy
    compares them with Python floats."""
    h, w = evidence.shape
    n = steps.size
    vals = np.empty(n, np.float32)
    inside = np.empty(n, np.bool_)
    first_outside = -1
    for k in range(n):
        r = end[0] + steps[k] * t[0]
        c = end[1] + steps[k] * t[1]
        inside[k] = r >= -0.5 and r <= h - 0.5 and c >= -0.5 and c <= w - 0.5
        if first_outside < 0 and not inside[k]:
            first_outside = k
        vals[k] = _bilinear(evidence, np.float32(r), np.float32(c))
    peak = vals[0]
    for k in range(1, min(n, 8)):
        peak = max(peak, vals[k])
    peak64 = np.float64(peak)
    level15 = np.float32(max(0.15 * peak64, 0.5 * floor))
    level35 = np.float32(max(0.35 * peak64, floor))
    k15 = -1
    k35 = -1
    for k in range(n):
        if k35 < 0 and vals[k] < level35 and inside[k]:
            k35 = k
        if vals[k] < level15 and inside[k]:
            k15 = k
            break
    if k35 < 0:
        if first_outside < 0:
            return False, 0.0
        return True, steps[first_outside - 1 if first_outside > 0 else n - 1]
    if k15 == 0:
        return True, 0.0
    level60 = np.float32(max(0.6 * peak64, floor))
    k60 = k35
    for k in range(k35):
        if vals[k] < level60:
            k60 = k
            break
    lo, hi = max(k60 - 1, 0), min(k35 + 1, n - 1)
    k, best = lo, _gradient(vals, lo)
    for j in range(lo + 1, hi + 1):              # steepest fall (first of equals)
        g = _gradient(vals, j)
        if g < best:
            k, best = j, g
    return True, steps[k] + np.float64(np.float32(0.25) * _parabola_vertex(vals, k)) - half_width_px


def edge_positions(profiles: np.ndarray, offsets: np.ndarray, floor: float, core_px: float):
    """Sub-pixel offsets of the left and right edges of the object in each profile: the points of
    steepest evidence change (the physical boundary for a flat ink stroke, whose half-maximum it is, and
    for a shaded round rod, whose dim flanks a fixed fraction of the peak would cut off), searched between
    the crossings of 15 % and 60 % of the peak (the profile's maximum within ``core_px`` of the path; the
    levels at least ``floor`` / 2 and ``floor``). nan where an edge is not found. ``profiles``: float32
    (as :func:`edge_profiles` gives them), compiled, one pass per profile."""
    profiles = np.ascontiguousarray(profiles, dtype=np.float32)
    offsets = np.ascontiguousarray(offsets, dtype=np.float64)
    core = np.flatnonzero(np.abs(offsets) <= core_px)
    e_l, e_r = np.empty(len(profiles)), np.empty(len(profiles))
    _edge_positions(profiles, offsets, float(floor), int(core[0]), int(core[-1]), e_l, e_r)
    return e_l, e_r


@njit(cache=True, nogil=True)
def _edge_positions(profiles, offsets, floor, core_first, core_last, e_l, e_r):
    """For each profile p: its peak over [core_first, core_last]; the nearest crossings, left and right of
    the centre sample, of the levels 15 % (at least floor / 2) and 60 % (at least floor) of it; the
    steepest rise of p (central differences) from one step outside the outer crossing to one step inside
    the inner one on the left, the steepest fall likewise on the right, refined by a parabola. float32
    arithmetic where the profiles are float32, float64 for offsets, as numpy does it."""
    n, k = profiles.shape
    c = k // 2
    step = offsets[1] - offsets[0]
    outer_floor, inner_floor = np.float32(0.5 * floor), np.float32(floor)
    for i in range(n):
        p = profiles[i]
        peak = p[core_first]
        for j in range(core_first + 1, core_last + 1):
            peak = max(peak, p[j])
        out_l, out_r = _level_crossings(p, offsets, max(np.float32(0.15) * peak, outer_floor), c, step)
        in_l, in_r = _level_crossings(p, offsets, max(np.float32(0.6) * peak, inner_floor), c, step)
        lo_l, hi_l = _search(offsets, out_l - step, False), _search(offsets, in_l + step, True)
        lo_r, hi_r = _search(offsets, in_r - step, False), _search(offsets, out_r + step, True)
        if not (np.isfinite(out_l) and np.isfinite(in_l) and lo_l < hi_l and lo_r < hi_r):
            e_l[i] = np.nan
            e_r[i] = np.nan
            continue
        jl, best = lo_l, _gradient(p, lo_l)
        for j in range(lo_l + 1, hi_l):                 # steepest rise on the left (first of equals)
            g = _gradient(p, j)
            if g > best:
                jl, best = j, g
        jr, best = lo_r, _gradient(p, lo_r)
        for j in range(lo_r + 1, hi_r):                 # steepest fall on the right
            g = _gradient(p, j)
            if g < best:
                jr, best = j, g
        e_l[i] = offsets[jl] + step * _parabola_vertex(p, jl)
        e_r[i] = offsets[jr] + step * _parabola_vertex(p, jr)


@njit(cache=True, nogil=True)
def _level_crossings(p, offsets, level, c, step):
    """Sub-pixel offsets of the nearest crossings of ``level`` left and right of sample ``c`` (linear
    interpolation); nan, nan if p[c] is below it or either side never falls below it."""
    k = p.size
    jl, jr = -1, -1
    if not p[c] < level:
        for j in range(c, -1, -1):
            if p[j] < level:
                jl = j
                break
        for j in range(c, k):
            if p[j] < level:
                jr = j
                break
    if jl < 0 or jr < 0:
        return np.nan, np.nan
    tiny = np.float32(1e-6)
    above = min(jl + 1, k - 1)
    denom = p[above] - p[jl]
    if abs(denom) < tiny:
        denom = tiny
    o_l = offsets[jl] + step * (level - p[jl]) / denom
    inside = max(jr - 1, 0)
    denom = p[jr] - p[inside]
    if abs(denom) < tiny:
        denom = tiny
    o_r = offsets[inside] + step * (level - p[inside]) / denom
    return o_l, o_r


@njit(cache=True, nogil=True)
def _search(offsets, value, right):
    """``np.searchsorted(offsets, value, 'right' if right else 'left')`` of the ascending ``offsets`` (nan: past
    the end): the first index whose offset is above ``value`` (at or above it: 'left'), by bisection."""
    if np.isnan(value):
        return offsets.size
    lo, hi = 0, offsets.size
    while lo < hi:
        mid = (lo + hi) // 2
        if offsets[mid] > value if right else offsets[mid] >= value:
            hi = mid
        else:
            lo = mid + 1
    return lo


@njit(cache=True, nogil=True)
def _gradient(p, j):
    """``np.gradient(p)[j]``: central difference, one-sided at the ends."""
    if j == 0:
        return p[1] - p[0]
    if j == p.size - 1:
        return p[j] - p[j - 1]
    return (p[j + 1] - p[j - 1]) * np.float32(0.5)


@njit(cache=True, nogil=True)
def _parabola_vertex(p, j):
    """Sub-sample offset (in [-0.5, 0.5]) of the extremum of the gradient of ``p`` (:func:`_gradient`) at ``j``:
    the vertex of the parabola through the gradient at j - 1, j, j + 1 (clamped to the profile), in float32
    (as numpy computes it on float32 profiles; a minimum gives the same offset as the maximum of -g)."""
    k = p.size
    a = _gradient(p, min(max(j - 1, 0), k - 1))
    b = _gradient(p, j)
    c = _gradient(p, min(max(j + 1, 0), k - 1))
    denom = a - (b + b) + c
    if abs(denom) > np.float32(1e-9):
        d = np.float32(0.5) * (a - c) / denom
    else:
        d = np.float32(0.0)
    return min(max(d, np.float32(-0.5)), np.float32(0.5))


def rod_share_profiles(bgr: np.ndarray, background, points: np.ndarray, normals: np.ndarray,
                       offsets: np.ndarray, excluded: np.ndarray, min_chroma_distance: float = 0.05,
                       min_brightness_ratio: float = 0.5):
    """The rod's share of the light across the path: float32 (n, k) profiles at ``offsets`` along the
    ``normals`` of ``points``, or None where the rod's colour does not stand out from the table's. Each
    sample's colour I (BGR, bilinear) is split by least squares into I = alpha c_rod + beta c_table, with
    c the chromaticities (B, G, R) / (B + G + R) of the rod (the median over the path points not
    ``excluded``) and of the table (``background``, an image or one BGR colour as
    :func:`~.segmentation.estimate_background` gives it, at the path point); alpha is the profile. A pixel
    a fraction a of which the rod covers has alpha = a times the rod's brightness there: a shadow on the
    table goes into beta, and the dim flank of a round rod keeps alpha at about the ambient share of the
    lit flank's, so the steepest change of alpha is the rod's edge even where the evidence |I - B| of the
    dark flank is as low as the table's and the shadow's beside it as high as the rod's. None when fewer
    than 3 points count, the two chromaticities are less than ``min_chroma_distance`` apart (median over
    the path: the split would be noise), or the table's brightness B + G + R (median along the path) and the
    rod's (at the path points, median) differ by more than a factor 1 / ``min_brightness_ratio``: a rod's
    flank fades into a table only about as bright as the rod, elsewhere the evidence's edges hold, and the
    darker one's chromaticity is noise (on the published mBEST photos, cables on a black cloth, the split's
    edges lay about 1.5 px inside the cables'; dark ink on paper: its ends were placed 2-3 px off)."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    normals = np.ascontiguousarray(normals, dtype=np.float64)
    offsets = np.ascontiguousarray(offsets, dtype=np.float64)
    if isinstance(background, np.ndarray):
        table = np.empty((len(points), 3))
        brightness = float(_table_chroma(np.ascontiguousarray(background), points, table))
    else:
        if len(background) != 3:
            raise ValueError(f'background must be a BGR image or one BGR colour, got {background!r}')
        colour = np.asarray(background, dtype=np.float64)
        brightness = float(colour.sum())
        table = np.tile(colour / max(brightness, 1e-9), (len(points), 1))
    share = np.empty((len(points), len(offsets)), np.float32)
    found = _rod_share(np.ascontiguousarray(bgr), points, normals, offsets, table, brightness,
                       np.ascontiguousarray(excluded, dtype=np.bool_), float(min_chroma_distance),
                       float(min_brightness_ratio), share)
    return share if found else None


@njit(cache=True, nogil=True)
def _table_chroma(background, points, out):
    """out[i] = chromaticity of the BGR ``background`` image at the pixel nearest to points[i]; returns the
    median brightness B + G + R there."""
    h, w, _ = background.shape
    totals = np.empty(points.shape[0])
    for i in range(points.shape[0]):
        r = min(max(int(np.rint(points[i, 0])), 0), h - 1)
        c = min(max(int(np.rint(points[i, 1])), 0), w - 1)
        total = np.float64(background[r, c, 0]) + np.float64(background[r, c, 1]) + np.float64(background[r, c, 2])
        totals[i] = total
        for ch in range(3):
            out[i, ch] = background[r, c, ch] / max(total, 1e-9)
    return _sorted_median(totals)


@njit(cache=True, nogil=True)
def _colour_at(bgr, r, c, out):
    """The BGR colour of the image at float (row, col), bilinear per channel (:func:`_bilinear`)."""
    for ch in range(3):
        out[ch] = _bilinear(bgr[:, :, ch], np.float32(r), np.float32(c))


@njit(cache=True, nogil=True)
def _rod_share(bgr, points, normals, offsets, table, table_brightness, excluded, min_distance, min_brightness_ratio,
               share):
    """:func:`rod_share_profiles`: False where the rod's colour does not stand out, else True, ``share`` set."""
    n, k = share.shape
    centre = np.empty((n, 3))
    brightness = np.empty(n)                 # B + G + R at each path point
    colour = np.empty(3)
    counted = 0
    for i in range(n):
        _colour_at(bgr, points[i, 0], points[i, 1], colour)
        brightness[i] = colour[0] + colour[1] + colour[2]
        total = max(brightness[i], 1e-9)
        for ch in range(3):
            centre[i, ch] = colour[ch] / total
        if not excluded[i]:
            counted += 1
    if counted < 3:
        return False
    column = np.empty(counted)
    m = 0
    for i in range(n):
        if not excluded[i]:
            column[m] = brightness[i]
            m += 1
    rod_brightness = _sorted_median(column)     # the cheaper test first (either failing gives False)
    if table_brightness < min_brightness_ratio * rod_brightness or \
            rod_brightness < min_brightness_ratio * table_brightness:
        return False
    rod = np.empty(3)
    for ch in range(3):
        m = 0
        for i in range(n):
            if not excluded[i]:
                column[m] = centre[i, ch]
                m += 1
        rod[ch] = _sorted_median(column)
    m = 0
    for i in range(n):
        if not excluded[i]:
            column[m] = np.sqrt((rod[0] - table[i, 0]) ** 2 + (rod[1] - table[i, 1]) ** 2
                                + (rod[2] - table[i, 2]) ** 2)
            m += 1
    if _sorted_median(column) < min_distance:
        return False
    for i in range(n):
        # alpha = row 0 of (M^T M)^-1 M^T, M = [c_rod c_table]
        rr = rod[0] * rod[0] + rod[1] * rod[1] + rod[2] * rod[2]
        tt = table[i, 0] ** 2 + table[i, 1] ** 2 + table[i, 2] ** 2
        rt = rod[0] * table[i, 0] + rod[1] * table[i, 1] + rod[2] * table[i, 2]
        det = rr * tt - rt * rt
        for j in range(k):
            if det < 1e-12:
                share[i, j] = np.nan
                continue
            _colour_at(bgr, points[i, 0] + offsets[j] * normals[i, 0], points[i, 1] + offsets[j] * normals[i, 1],
                       colour)
            ir = colour[0] * rod[0] + colour[1] * rod[1] + colour[2] * rod[2]
            it = colour[0] * table[i, 0] + colour[1] * table[i, 1] + colour[2] * table[i, 2]
            share[i, j] = (tt * ir - rt * it) / det
    return True


def refine(points: np.ndarray, closed: bool, evidence: np.ndarray, approx_width_px: float,
           floor: float, exclude=None, sigma_px: float = 1.5, colour=None) -> RefinedPath:
    """Edge-centred, smoothed path at 1 px spacing (see module docstring); ``exclude(points)`` returns a
    bool mask of points whose profile must not be trusted, e.g. inside crossings; ``colour``: (BGR image,
    background), to find the edges in the rod's share of the light (:func:`rod_share_profiles`) where the
    rod's colour stands out from a table about as bright as the rod; elsewhere, and without it, in
    ``evidence``.
    Profiles span 0.8 ``approx_width_px`` + 3 px either side of the path."""
    pts = resample(points, 1.0)
    if len(pts) < 3:
        return RefinedPath(pts, float('nan'), closed, np.full(len(pts), np.nan))
    pts = smooth(pts, 1.0, closed)
    t = tangents(smooth(pts, 2.0, closed), closed)
    normals = np.stack([t[:, 1], -t[:, 0]], axis=1)
    # profiles every second point (the correction is smooth along the path), both ends included
    idx = np.arange(0, len(pts), 2)
    if idx[-1] != len(pts) - 1:
        idx = np.append(idx, len(pts) - 1)
    half_span = 0.8 * approx_width_px + 3.0
    excluded = exclude(pts[idx]) if exclude is not None else np.zeros(len(idx), np.bool_)
    offsets = profile_offsets(half_span)
    share = None if colour is None else rod_share_profiles(colour[0], colour[1], pts[idx], normals[idx], offsets,
                                                           excluded)
    if share is None:               # the evidence's profiles, sampled only where the rod's share is not used
        prof, _ = edge_profiles(evidence, pts[idx], normals[idx], half_span)
        o_l, o_r = edge_positions(prof, offsets, floor, core_px=0.5 * approx_width_px + 1.0)
    else:
        o_l, o_r = edge_positions(share, offsets, 0.0, core_px=0.5 * approx_width_px + 1.0)
    delta, widths = np.empty(len(pts)), np.empty(len(pts))
    w_obj = _edge_correction(idx, o_l, o_r, np.ascontiguousarray(excluded, dtype=np.bool_), delta, widths)
    if np.isfinite(w_obj):
        delta = gaussian_filter(delta, 2.0, wrap=closed)
        pts = pts + delta[:, None] * normals
    pts = smooth(pts, sigma_px, closed)
    if closed:
        pts[-1] = pts[0]
    return RefinedPath(pts, w_obj, closed, widths)


@njit(cache=True, nogil=True)
def _edge_correction(idx, o_l, o_r, excluded, delta, widths):
    """The edge-centred correction of :func:`refine` from the edges ``o_l``, ``o_r`` found at the path points
    ``idx``: a point counts where both edges are found, it is not ``excluded``, and (with 3 such points
    or more) its width lies within 0.6-1.4 of their median and its centre offset within 0.35 of it + 1 px.
    ``widths`` (per path point): the width where it counts, else nan; ``delta``: the centre offsets
    interpolated along the path (np.interp's arithmetic: slope (x - x_j) + y_j, the end values beyond) if 3
    or more count. Returns the median width of those (np.median), nan if fewer than 3 count."""
    m = idx.size
    width = o_r - o_l
    centre = 0.5 * (o_l + o_r)
    ok = np.empty(m, np.bool_)
    for k in range(m):
        ok[k] = np.isfinite(width[k]) and not excluded[k]
    if ok.sum() >= 3:
        w_med = _sorted_median(width[ok])
        for k in range(m):
            ok[k] = ok[k] and width[k] > 0.6 * w_med and width[k] < 1.4 * w_med and \
                abs(centre[k]) < 0.35 * w_med + 1.0
    widths[:] = np.nan
    for k in range(m):
        if ok[k]:
            widths[idx[k]] = width[k]
    if ok.sum() < 3:
        return np.nan
    xp = idx[ok].astype(np.float64)
    fp = centre[ok]
    last = xp.size - 1
    j = 0
    for i in range(delta.size):
        x = np.float64(i)
        while j < last and xp[j + 1] <= x:
            j += 1
        if x < xp[0]:
            delta[i] = fp[0]
        elif x > xp[last]:
            delta[i] = fp[last]
        elif j == last or xp[j] == x:
            delta[i] = fp[j]
        else:
            delta[i] = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j]) * (x - xp[j]) + fp[j]
    return _sorted_median(width[ok])


@njit(cache=True, nogil=True)
def _sorted_median(values):
    """np.median of a 1-D float64 array without nan."""
    s = np.sort(values)
    h = s.size // 2
    return s[h] if s.size % 2 else (s[h - 1] + s[h]) / 2


def _median(values: np.ndarray):
    """``np.median`` of a 1-D float array without nan (the middle of the sorted values, or the mean of the two
    middle ones), without its per-call overhead."""
    s = np.sort(values)
    h = len(s) // 2
    return s[h] if len(s) % 2 else (s[h - 1] + s[h]) / 2


def place_ends(path: RefinedPath, evidence: np.ndarray, floor: float, half_width_px: float,
               tangent_px: float) -> RefinedPath:
    """Move each open end to half a width inside the boundary met along the end tangent (or to the image
    border when the object runs off the image); extension along the tangent, trimming along the path. The
    boundary is searched within the trimmed stretch + 2 half widths + 4 px, and where not found there, within
    one width more."""
    if path.closed or len(path.points) < 3:
        return path
    pts = path.points
    for end in (0, 1):
        p = pts if end == 1 else pts[::-1]
        s = arc_length(p)
        # drop the last ~half width (thinning bends it towards a corner of a flat end), take the tangent
        # from the stretch before it
        trim = min(0.6 * half_width_px * 2.0, 0.25 * s[-1])
        keep = int(np.searchsorted(s, s[-1] - trim, side='right'))
        keep = max(keep, 2)
        p = p[:keep]
        s = s[:keep]
        j = int(np.searchsorted(s, s[-1] - tangent_px))
        j = min(max(j, 0), len(p) - 2)
        t = p[-1] - p[j]
        nt = np.linalg.norm(t)
        if nt < 1e-9:
            continue
        t /= nt
        # the boundary within reach; where there is none (thinning can stop about a width inside the tip, the
        # foot then just past the reach), a second search one width further before the end is left as it was
        # (a blob?)
        reach = trim + 2.0 * half_width_px + 4.0
        for r in (reach, reach + 2.0 * half_width_px):
            found, target = _end_target(evidence, p[-1], t, np.arange(0.0, r + 1e-9, 0.25), float(floor),
                                        float(half_width_px))
            if found:
                break
        if not found:
            continue
        if target > 0.5:
            extra = np.arange(1.0, target + 1e-9, 1.0)
            if extra.size == 0 or extra[-1] < target - 1e-6:
                extra = np.append(extra, target)
            p = np.vstack([p, p[-1] + extra[:, None] * t[None, :]])
        elif target < -0.5:
            cut = min(-target, 0.5 * half_width_px + 1.0, 0.3 * s[-1])
            keep = s <= s[-1] - cut
            last = np.interp(s[-1] - cut, s, np.arange(len(p)))
            i0 = int(np.floor(last))
            frac = last - i0
            q = p[i0] + frac * (p[min(i0 + 1, len(p) - 1)] - p[i0])
            p = np.vstack([p[keep], q[None]])
        pts = p if end == 1 else p[::-1]
    return RefinedPath(pts, path.width_px, path.closed, path.widths)
