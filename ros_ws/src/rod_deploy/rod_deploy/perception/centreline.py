"""Sub-pixel centreline: edge-centred refinement, smoothing, end placement and arc-length resampling.

A skeleton is a chain of pixel centres, up to half a pixel off the true centre line and shortened or
lengthened at the ends. For each point of a traced path the foreground evidence is sampled (bilinearly)
across the path, the two edges (steepest change of evidence, found to sub-pixel precision) are located,
and the point moves to their midpoint; the distance between them is the local width.
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

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter1d


@dataclass
class RefinedPath:
    points: np.ndarray          # (n, 2) (row, col) [px]
    width_px: float             # median measured width (nan if never measured)
    closed: bool
    widths: np.ndarray          # measured width [px] per point of refine()'s output (nan: not measured);
                                # place_ends() keeps it as is


def arc_length(points: np.ndarray) -> np.ndarray:
    if len(points) < 2:
        return np.zeros(len(points))
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])


def resample(points: np.ndarray, step_px: float) -> np.ndarray:
    """Points at equal arc-length spacing (last spacing at most ``step_px``), both ends kept."""
    points = np.asarray(points, dtype=np.float64)
    s = arc_length(points)
    keep = np.concatenate([[True], np.diff(s) > 1e-9])
    points, s = points[keep], s[keep]
    if len(points) < 2 or s[-1] <= 0:
        return points[:1].copy()
    n = max(2, int(np.ceil(s[-1] / step_px)) + 1)
    t = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(t, s, points[:, 0]), np.interp(t, s, points[:, 1])], axis=1)


def smooth(points: np.ndarray, sigma_pts: float, closed: bool) -> np.ndarray:
    """Gaussian smoothing along the point index (points at ~equal spacing). Open paths use odd (point)
    reflection at the ends, which keeps the end points and straight end tangents unbiased."""
    if sigma_pts <= 0 or len(points) < 3:
        return points.copy()
    if closed:
        body = points[:-1]
        out = gaussian_filter1d(body, sigma_pts, axis=0, mode='wrap')
        return np.vstack([out, out[:1]])
    pad = min(len(points) - 1, int(np.ceil(4 * sigma_pts)))
    head = 2 * points[0] - points[pad:0:-1]
    tail = 2 * points[-1] - points[-2:-pad - 2:-1]
    ext = np.vstack([head, points, tail])
    out = gaussian_filter1d(ext, sigma_pts, axis=0, mode='nearest')
    return out[pad:pad + len(points)]


def tangents(points: np.ndarray, closed: bool) -> np.ndarray:
    if len(points) < 2:
        return np.tile([0.0, 1.0], (len(points), 1))
    if closed:
        body = points[:-1]
        t = np.roll(body, -1, axis=0) - np.roll(body, 1, axis=0)
        t = np.vstack([t, t[:1]])
    else:
        t = np.gradient(points, axis=0)
    norm = np.linalg.norm(t, axis=1, keepdims=True)
    norm[norm == 0] = 1.0
    return t / norm


def edge_profiles(evidence: np.ndarray, points: np.ndarray, normals: np.ndarray, half_span_px: float,
                  step_px: float = 0.5):
    """Evidence sampled across the path: (n, k) profiles at offsets (k,) [px] along the normals."""
    offsets = np.arange(-half_span_px, half_span_px + 1e-9, step_px)
    rows = points[:, 0:1] + offsets[None, :] * normals[:, 0:1]
    cols = points[:, 1:2] + offsets[None, :] * normals[:, 1:2]
    prof = cv2.remap(evidence, cols.astype(np.float32), rows.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)
    return prof, offsets


def level_crossings(profiles: np.ndarray, offsets: np.ndarray, fraction: float, floor: float,
                    core_px: float, peak: np.ndarray | None = None):
    """Sub-pixel offsets of the nearest crossings, left and right of the path, of ``fraction`` of each
    profile's peak within ``core_px`` of the path (at least ``floor``); nan where there is none.
    ``peak``: that peak per profile, if already known."""
    k = profiles.shape[1]
    c = k // 2
    if peak is None:
        peak = _core_peak(profiles, offsets, core_px)
    level = np.maximum(fraction * peak, floor)
    below = profiles < level[:, None]
    idx = np.arange(len(profiles))
    left_below = below[:, c::-1]                             # from the path outwards to the left
    dl = np.argmax(left_below, axis=1)
    right_below = below[:, c:]
    dr = np.argmax(right_below, axis=1)
    valid = ~below[:, c] & left_below[idx, dl] & right_below[idx, dr]     # (argmax of no True: 0)
    jl = c - dl                                              # last index <= c below the level
    jr = c + dr                                              # first index >= c below the level
    step = offsets[1] - offsets[0]

    def interp(j_lo, j_hi):
        p_lo, p_hi = profiles[idx, j_lo], profiles[idx, j_hi]
        denom = p_hi - p_lo
        denom[np.abs(denom) < 1e-6] = 1e-6
        return offsets[j_lo] + step * (level - p_lo) / denom

    o_l = interp(jl, np.minimum(jl + 1, k - 1))
    o_r = interp(np.maximum(jr - 1, 0), jr)
    o_l[~valid] = np.nan
    o_r[~valid] = np.nan
    return o_l, o_r


def _core_peak(profiles: np.ndarray, offsets: np.ndarray, core_px: float) -> np.ndarray:
    """Maximum of each profile within ``core_px`` of the path (offsets ascending, so a slice)."""
    core = np.flatnonzero(np.abs(offsets) <= core_px)
    return profiles[:, core[0]:core[-1] + 1].max(axis=1)


def _parabolic_peak(g: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Sub-sample offset of the maximum of each row of ``g`` near index ``j`` (parabola through 3); the
    same for the minimum (``-g`` gives exactly the same result)."""
    idx = np.arange(len(g))
    jm = np.clip(j - 1, 0, g.shape[1] - 1)
    jp = np.clip(j + 1, 0, g.shape[1] - 1)
    a, b, c = g[idx, jm], g[idx, j], g[idx, jp]
    denom = a - 2 * b + c
    with np.errstate(invalid='ignore', divide='ignore'):
        d = np.where(np.abs(denom) > 1e-9, 0.5 * (a - c) / denom, 0.0)
    return np.clip(d, -0.5, 0.5)


def edge_positions(profiles: np.ndarray, offsets: np.ndarray, floor: float, core_px: float):
    """Sub-pixel offsets of the left and right edges of the object in each profile: the points of
    steepest evidence change (the physical boundary for a flat ink stroke, whose half-maximum it is, and
    for a shaded round rod, whose dim flanks a fixed fraction of the peak would cut off), searched between
    the crossings of 15 % and 60 % of the peak. nan where an edge is not found."""
    peak = _core_peak(profiles, offsets, core_px)
    out_l, out_r = level_crossings(profiles, offsets, 0.15, 0.5 * floor, core_px, peak)
    in_l, in_r = level_crossings(profiles, offsets, 0.6, floor, core_px, peak)
    g = np.gradient(profiles, axis=1)
    step = offsets[1] - offsets[0]
    # search windows [lo, hi) of offset indices: from one step outside the outer crossing to one step
    # inside the inner one (nan: empty or open-ended, and then the row is dropped anyway)
    lo_l, hi_l = offsets.searchsorted(out_l - step, 'left'), offsets.searchsorted(in_l + step, 'right')
    lo_r, hi_r = offsets.searchsorted(in_r - step, 'left'), offsets.searchsorted(out_r + step, 'right')
    j = np.arange(len(offsets), dtype=np.int32)
    win_l = (j >= lo_l.astype(np.int32)[:, None]) & (j < hi_l.astype(np.int32)[:, None])
    win_r = (j >= lo_r.astype(np.int32)[:, None]) & (j < hi_r.astype(np.int32)[:, None])
    jl = np.argmax(np.where(win_l, g, -np.inf), axis=1)      # steepest rise on the left
    jr = np.argmin(np.where(win_r, g, np.inf), axis=1)       # steepest fall on the right
    e_l = offsets[jl] + step * _parabolic_peak(g, jl)
    e_r = offsets[jr] + step * _parabolic_peak(g, jr)
    bad = ~(np.isfinite(out_l) & np.isfinite(in_l) & (lo_l < hi_l) & (lo_r < hi_r))
    e_l[bad] = np.nan
    e_r[bad] = np.nan
    return e_l, e_r


def refine(points: np.ndarray, closed: bool, evidence: np.ndarray, approx_width_px: float,
           floor: float, exclude=None, sigma_px: float = 1.5) -> RefinedPath:
    """Edge-centred, smoothed path at 1 px spacing (see module docstring); ``exclude(points)`` returns a
    bool mask of points whose profile must not be trusted, e.g. inside crossings."""
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
    prof, offsets = edge_profiles(evidence, pts[idx], normals[idx], half_span)
    o_l, o_r = edge_positions(prof, offsets, floor, core_px=0.5 * approx_width_px + 1.0)
    width = o_r - o_l
    centre = 0.5 * (o_l + o_r)
    ok = np.isfinite(width)
    if exclude is not None:
        ok &= ~exclude(pts[idx])
    if ok.sum() >= 3:
        w_med = float(np.median(width[ok]))
        ok &= (width > 0.6 * w_med) & (width < 1.4 * w_med) & (np.abs(centre) < 0.35 * w_med + 1.0)
    widths = np.full(len(pts), np.nan)
    widths[idx[ok]] = width[ok]
    if ok.sum() >= 3:
        i = np.arange(len(pts))
        delta = np.interp(i, idx[ok], centre[ok])
        delta = gaussian_filter1d(delta, 2.0, mode='wrap' if closed else 'nearest')
        pts = pts + delta[:, None] * normals
        w_obj = float(np.median(width[ok]))
    else:
        w_obj = float('nan')
    pts = smooth(pts, sigma_px, closed)
    if closed:
        pts[-1] = pts[0]
    return RefinedPath(pts, w_obj, closed, widths)


def place_ends(path: RefinedPath, evidence: np.ndarray, floor: float, half_width_px: float,
               tangent_px: float) -> RefinedPath:
    """Move each open end to half a width inside the boundary met along the end tangent (or to the image
    border when the object runs off the image); extension along the tangent, trimming along the path."""
    if path.closed or len(path.points) < 3:
        return path
    pts = path.points
    h, w = evidence.shape
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
        reach = trim + 2.0 * half_width_px + 4.0
        steps = np.arange(0.0, reach + 1e-9, 0.25)
        ray = p[-1][None, :] + steps[:, None] * t[None, :]
        inside = (ray[:, 0] >= -0.5) & (ray[:, 0] <= h - 0.5) & (ray[:, 1] >= -0.5) & (ray[:, 1] <= w - 0.5)
        vals = cv2.remap(evidence, ray[:, 1].astype(np.float32)[None], ray[:, 0].astype(np.float32)[None],
                         cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)[0]
        peak = float(vals[: max(1, int(2 / 0.25))].max())
        below = (vals < max(0.15 * peak, 0.5 * floor)) & inside
        if below.any():
            k15 = int(np.argmax(below))
            if k15 == 0:            # the end is already outside: keep it where thinning left it
                target = 0.0
            else:                   # boundary: steepest fall between 60 % and 15 % of the peak
                k60 = int(np.argmax(np.append(vals[:k15] < max(0.6 * peak, floor), True)))
                g = -np.gradient(vals)
                lo, hi = max(k60 - 1, 0), min(k15 + 1, len(vals) - 1)
                k = lo + int(np.argmax(g[lo:hi + 1]))
                d = _parabolic_peak(g[None, :], np.array([k]))[0]
                b = steps[k] + 0.25 * d
                target = b - half_width_px
        elif not inside.all():      # ran off the image while still on the object: stop at the border
            target = steps[int(np.argmin(inside)) - 1]
        else:                       # no boundary within reach (a blob?): leave this end as it was
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
