"""Two rods lying side by side along a stretch: each path moved onto its own rod.

Where two rods touch along a length (a shallow crossing whose rods run on together, two rods lying along each
other between two crossings, rods side by side into a shared end), the mask holds one strip as wide as both
rods, its skeleton runs down the strip's middle, and both traced paths follow that middle: each rod's path
lies about half the other rod's width off its own centreline. Edge-centred refinement cannot tell, since the
strip's two edges are one edge of each rod.

The stretch gives itself away by the two paths running together (within ``coincide_factor`` w of each other,
w the narrower rod's width) over at least ``min_run_factor`` W (W the wider rod's width; at a plain shallow
crossing the paths meet over a shorter stretch and are left alone). Along it, each rod lies against one edge
of the strip: rod i's centreline is ``w_i / 2`` inside the strip's edge on its side (exact for two strips
that overlap or touch, whatever their widths, as long as neither lies wholly inside the other). The strip's
edges come from the mask across the path (its 0.5 level, bilinear), and both rods' widths are measured the
same way where each lies alone, so that the mask's bias (blur, shadows) cancels. Each offset is weighted
by how clearly the strip holds two rods there (0 where it is no wider than the wider rod, 1 from half the
narrower rod wider). Where the strip narrows to one rod the rods cross and swap sides. Which side rod i
lies on: for rods of clearly different colours (median CIELAB a*b* over each path farther apart than
``min_colour_separation``), where the colours at the two candidate centres match, on each piece between
crossings; for rods of one colour, from where the two rods part at either end of the stretch (the side its
path leaves on, against the other path; where its own path ends inside the stretch, opposite to the other
rod's arm), each crossing along the stretch a swap, which must bring it out on the side seen at the far
end, and only when no crossing the graph found between the two rods lies near the stretch (a rod that
crosses the other where they meet, then lies alongside, leaves on the other side). The offsets, along the
path's normal, are smoothed along the path (Gaussian, 2 px). Units: pixels, points (row, col).
"""
from __future__ import annotations

import numpy as np

from rod_deploy.perception import centreline as cl
from rod_deploy.perception.nearest import nearest_distances

COINCIDE_FACTOR = 0.35   # two paths within this many (narrower) rod widths of each other run on one strip
MIN_RUN_FACTOR = 3.0     # ... over at least this many (wider) rod widths


def mask_edges(mask: np.ndarray, points: np.ndarray, normals: np.ndarray, half_span_px: float,
               step_px: float = 0.25):
    """(lo, hi): offsets [px] along ``normals`` from each of ``points`` to the bool ``mask``'s boundary
    (its bilinear 0.5 level, searched outwards from the point); nan where the point is outside the mask or
    no boundary lies within ``half_span_px``."""
    prof, off = cl.edge_profiles(mask.view(np.uint8), points, normals, half_span_px, step_px)
    c = len(off) // 2
    lo, hi = np.full(len(points), np.nan), np.full(len(points), np.nan)
    for k in range(len(points)):
        p = prof[k]
        if p[c] < 0.5:
            continue
        out_r = np.flatnonzero(p[c:] < 0.5)
        if len(out_r):
            j = c + int(out_r[0])
            hi[k] = off[j - 1] + (p[j - 1] - 0.5) / (p[j - 1] - p[j]) * step_px
        out_l = np.flatnonzero(p[:c + 1][::-1] < 0.5)
        if len(out_l):
            j = c - int(out_l[0])
            lo[k] = off[j + 1] - (p[j + 1] - 0.5) / (p[j + 1] - p[j]) * step_px
    return lo, hi


def _normals(a, closed):
    """Unit normals (n, 2) of path ``a``: its tangents after a 2 px Gaussian smoothing, turned by -90 degrees."""
    t = cl.tangents(cl.smooth(a, 2.0, closed), closed)
    return np.stack([t[:, 1], -t[:, 0]], axis=1)


def _runs(flags, min_len):
    """(first, last) index ranges of the runs of True at least ``min_len`` long."""
    out, i, n = [], 0, len(flags)
    while i < n:
        if flags[i]:
            j = i
            while j + 1 < n and flags[j + 1]:
                j += 1
            if j - i + 1 >= min_len:
                out.append((i, j))
            i = j + 1
        else:
            i += 1
    return out


def _first_apart(p, start, step, other, apart_px, reach):
    """The index of the first point of ``p`` from ``start`` on (``step`` = -1 or +1), within ``reach``
    points, that lies farther than ``apart_px`` from the path ``other``; None if there is none."""
    idx = np.arange(start, start + step * (reach + 1), step)
    idx = idx[(idx >= 0) & (idx < len(p))]
    if not len(idx):
        return None
    far = ~np.isfinite(nearest_distances(other, p[idx], apart_px))
    return int(idx[int(np.argmax(far))]) if far.any() else None


def _leaving_side(a, i_end, outward, b, normal, w, reach_factor=8.0):
    """(side, index): the side (+1 / -1 along ``normal``) on which path ``a`` leaves a shared stretch at its
    index ``i_end`` (``outward`` = -1: towards its start, +1: towards its end), relative to path ``b``, and
    the index of a's point where that is seen: where the two paths are first half a width ``w`` apart beyond
    the stretch (within ``reach_factor`` w). Where ``a`` ends inside the stretch: opposite to ``b``'s arm
    leaving there, seen at ``i_end``. (0, i_end) where neither path leaves there (both end inside it)."""
    reach = int(np.ceil(reach_factor * w))
    jb = int(np.argmin(np.hypot(b[:, 0] - a[i_end, 0], b[:, 1] - a[i_end, 1])))
    m = _first_apart(a, i_end, outward, b, 0.5 * w, reach)
    if m is not None:
        return float(np.sign(np.dot(a[m] - b[jb], normal))), m
    # b's arm beyond the stretch: the first point of either of its directions that leaves path a
    arms = [q for q in (_first_apart(b, jb, -1, a, 0.5 * w, reach), _first_apart(b, jb, 1, a, 0.5 * w, reach))
            if q is not None]
    if len(arms) == 1:
        return -float(np.sign(np.dot(b[arms[0]] - a[i_end], normal))), i_end
    return 0.0, i_end


def separate_side_by_side(paths: list, widths: list, closed: list, mask: np.ndarray, colours_at=None,
                          crossings=(), min_colour_separation: float = 12.0,
                          coincide_factor: float = COINCIDE_FACTOR, min_run_factor: float = MIN_RUN_FACTOR) -> list:
    """The (n, 2) ``paths`` (about 1 px steps; rod widths ``widths`` [px]; ``closed`` flags) with every
    stretch where two of them run together down one strip of the bool ``mask`` moved onto each rod's own
    side (see the module docstring). ``colours_at(points)``: CIELAB a*b* (n, 2) at (row, col) points (None:
    sides from geometry only); ``crossings``: (path i, path j, (row, col)) of the crossings found between
    two paths. Paths not involved are returned as they are (the same arrays)."""
    if len(paths) != len(widths) or len(paths) != len(closed):
        raise ValueError(f'{len(paths)} paths, {len(widths)} widths and {len(closed)} closed flags')
    out = list(paths)
    own_colour = {}
    for i in range(len(paths)):
        a = paths[i]
        if len(a) < 8:
            continue
        offsets = np.zeros(len(a))
        for j in range(len(paths)):
            b = paths[j]
            if j == i or len(b) < 8:
                continue
            w_min, w_max = min(widths[i], widths[j]), max(widths[i], widths[j])
            min_run = int(np.ceil(min_run_factor * w_max))
            # every fourth point first: most pairs of paths never run together
            if np.count_nonzero(np.isfinite(nearest_distances(b, a[::4], coincide_factor * w_min))) < min_run // 4:
                continue
            d = nearest_distances(b, a, coincide_factor * w_min)
            for lo_i, hi_i in _runs(np.isfinite(d), min_run):
                between = [np.asarray(p, float) for ci, cj, p in crossings if {ci, cj} == {i, j}]
                colours = None
                if colours_at is not None:
                    for k in (i, j):
                        if k not in own_colour:
                            own_colour[k] = np.median(colours_at(paths[k][::max(1, len(paths[k]) // 80)]), axis=0)
                    if np.linalg.norm(own_colour[i] - own_colour[j]) > min_colour_separation:
                        colours = (colours_at, own_colour[i], own_colour[j])
                delta = _stretch_offsets(a, lo_i, hi_i, b, w_min, w_max, closed[i], mask, colours, between)
                if delta is not None:
                    offsets[lo_i:hi_i + 1] = delta
        if not offsets.any():
            continue
        out[i] = a + cl.gaussian_filter(offsets, 2.0, wrap=closed[i])[:, None] * _normals(a, closed[i])
    return out


def _alone_width(a, b, closed, mask, w_max):
    """The median width [px] of the mask across path ``a`` where it lies farther than 1.5 ``w_max`` from
    path ``b`` (every second point), or None where fewer than 3 such widths are found."""
    far = nearest_distances(b, a[::2], 1.5 * w_max)
    alone = np.arange(0, len(a), 2)[~np.isfinite(far)]
    if len(alone) < 3:
        return None
    lo, hi = mask_edges(mask, a[alone], _normals(a, closed)[alone], w_max + 4.0)
    own = hi - lo
    return float(np.nanmedian(own)) if np.count_nonzero(np.isfinite(own)) >= 3 else None


def _stretch_offsets(a, lo_i, hi_i, b, w_min, w_max, closed, mask, colours=None, between=()):
    """Normal offsets [px] that move ``a[lo_i:hi_i + 1]`` (running together with path ``b``) onto its own
    side of the strip, or None when the rods' sides or a's own width are not found. Each offset is weighted
    by how clearly the strip there holds two rods: 0 where it is no wider than the wider rod (where the
    rods cross), 1 where it is at least half the narrower rod wider, linear between. The strip is cut where
    it narrows below half that weight (the rods cross there); on each piece a's side is where the colour
    ``colours`` = (colours_at, a's colour, b's colour) at the two candidate centres matches a's and b's
    (rods of different colours), else (one colour, no crossing ``between`` the two paths near the stretch)
    from where the paths part at its ends (:func:`_leaving_side`), each narrowing a flip, which must agree
    with the side at the far end."""
    n_all = _normals(a, closed)
    (s0, m0), (s1, m1) = (_leaving_side(a, lo_i, -1, b, n_all[lo_i], w_max),
                          _leaving_side(a, hi_i, +1, b, n_all[hi_i], w_max))
    # both rods' widths measured the same way as the strip, where each lies alone (farther than 1.5 W from
    # the other): the mask's edges lie off the rods' by the blur and the shadows, alike for all three
    w_own, w_other = _alone_width(a, b, closed, mask, w_max), _alone_width(b, a, closed, mask, w_max)
    if w_own is None or w_other is None:
        return None
    w_min, w_max = min(w_own, w_other), max(w_own, w_other)
    lo, hi = mask_edges(mask, a[lo_i:hi_i + 1], n_all[lo_i:hi_i + 1], 2.0 * w_max + 4.0)
    strip = hi - lo
    weight = np.clip((np.nan_to_num(strip, nan=0.0) - w_max) / (0.5 * w_min), 0.0, 1.0)
    if weight.max() < 0.5:
        return None
    seg_n = n_all[lo_i:hi_i + 1]
    c_hi = a[lo_i:hi_i + 1] + (hi - 0.5 * w_own)[:, None] * seg_n
    c_lo = a[lo_i:hi_i + 1] + (lo + 0.5 * w_own)[:, None] * seg_n
    # the rods cross wherever the strip narrows to one rod (running median of 3 of the weight below 1/2)
    smooth_w = (np.r_[weight[:1], np.median(np.lib.stride_tricks.sliding_window_view(weight, 3), axis=1),
                      weight[-1:]] if len(weight) >= 3 else weight)
    narrow = smooth_w < 0.5
    narrest = np.where(np.isfinite(strip), strip, np.inf)
    flips = [int(i0 + np.argmin(narrest[i0:i1 + 1])) for i0, i1 in _runs(narrow, 1)]
    sign = np.zeros(len(strip))
    if colours is not None:
        colours_at, col_a, col_b = colours
        cuts = [0] + flips + [len(strip)]
        for p0, p1 in zip(cuts[:-1], cuts[1:]):
            use = np.arange(p0, p1)[(~narrow[p0:p1]) & np.isfinite(strip[p0:p1])]
            if len(use) < 3:
                continue
            ch, cw = colours_at(c_hi[use]), colours_at(c_lo[use])
            # a on the high side: its colour there and b's on the low side, against the other way round
            vote = (np.linalg.norm(ch - col_a, axis=1) + np.linalg.norm(cw - col_b, axis=1)
                    - np.linalg.norm(ch - col_b, axis=1) - np.linalg.norm(cw - col_a, axis=1))
            sign[p0:p1] = -np.sign(np.median(vote))
    else:
        if s0 == 0 and s1 == 0:
            return None
        if any(np.min(np.hypot(*(a[m0:m1 + 1] - p).T)) <= w_max for p in between):
            return None             # the rods cross near the stretch: which side is not seen from its ends
        parity = (-1) ** len(flips)
        if s0 == 0:
            s0 = s1 * parity
        elif s1 != 0 and s0 * parity != s1:
            return None             # the sides and the crossings along the stretch disagree
        sign[:] = s0
        for k in flips:
            sign[k:] = -sign[k:]
    target = np.where(sign > 0, hi - 0.5 * w_own, np.where(sign < 0, lo + 0.5 * w_own, 0.0))
    return np.where(np.isfinite(target), target, 0.0) * weight
