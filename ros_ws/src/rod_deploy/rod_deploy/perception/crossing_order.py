"""Over/under order at crossings: from colour where the two strands differ, else from occlusion edges.

Where two strands cross, the pixels of the overlap show the upper strand. For every pair of strands
through a crossing, the overlap point is where their connectors come closest; the colour there (median
over a disc of a third of the stroke width) is compared, in CIELAB chromaticity (a*, b*: insensitive to
shading and glare), with each strand's own colour (median along the strand between 1.5 and 3.5 stroke
widths from the overlap, on both sides). The strand whose own colour is nearer is on top. Colours are
3x3 means, which keeps JPEG noise out. When the two strands' colours differ by less than
``min_colour_separation`` (e.g. a rod crossing itself) the occlusion edges decide
(:func:`occlusion_edge_strength`: the upper strand's boundary runs on through the overlap, the lower one's
is hidden), with confidence |e_a - e_b| / (e_a + e_b), each strand with its own width and direction
(the chord of its pass); the decision must hold with either direction turned by up to
``tangent_tolerance_rad`` (the chord's error at a thin rod on a thick one), and the confidence is the
worst case over those directions. Below ``min_edge_confidence`` (or at crossings shallower than about
12 degrees) the order is left undecided: a wrong order is worse than none.
Colour confidence = (d_under - d_over) / separation, in [0, 1] for a clean decision.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numba import njit

from rod_deploy.perception.fma import fma64


@dataclass
class CrossingDecision:
    crossing: int                    # crossing cluster id
    position: np.ndarray             # (row, col) [px] of the overlap
    objects: tuple                   # (object a, object b); equal for a self-crossing
    over: int | None                 # object id on top, None if undecided
    confidence: float                # 0 when undecided
    separation: float                # colour difference of the two strands [CIELAB a*b* units]
    spans: tuple = ()                # ((first, last) index range of the pass of a, same for b)
    cue: str | None = None           # what decided: 'colour', 'edges' (occlusion edges), None: undecided


def _lab(bgr_pixels: np.ndarray) -> np.ndarray:
    """(n, 3) CIELAB (L*, a*, b*) of BGR pixels (converted as one image row: OpenCV's vectorised path, 3x
    faster than a column of single pixels and the same numbers)."""
    px = np.asarray(bgr_pixels, dtype=np.float32).reshape(1, -1, 3) / 255.0
    return cv2.cvtColor(px, cv2.COLOR_BGR2Lab).reshape(-1, 3)


def _lab_ab(bgr_pixels: np.ndarray) -> np.ndarray:
    return _lab(bgr_pixels)[:, 1:]


def _sample(image: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Mean colour over the 3x3 pixels around each (row, col) point (cheaper than blurring the image)."""
    h, w = image.shape[:2]
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if h < 3 or w < 3:
        r = np.minimum(np.maximum(np.round(points[:, 0]).astype(np.intp), 1), max(h - 2, 1))
        c = np.minimum(np.maximum(np.round(points[:, 1]).astype(np.intp), 1), max(w - 2, 1))
        return image[np.minimum(r, h - 1), np.minimum(c, w - 1)].astype(np.float32)
    out = np.empty((len(points), image.shape[2]), np.float32)
    _mean3x3(np.ascontiguousarray(image), points, out)
    return out


@njit(cache=True, nogil=True)
def _mean3x3(image, points, out):
    """out[i] = the mean of the 3x3 pixels (per channel) around the pixel nearest to points[i] (rounded half
    to even, as np.round; clipped one pixel inside the border): the nine integers summed exactly, then one
    float32 division by 9, as numpy's float32 sum of them does."""
    h, w, k = image.shape
    for i in range(points.shape[0]):
        r = min(max(int(np.rint(points[i, 0])), 1), h - 2)
        c = min(max(int(np.rint(points[i, 1])), 1), w - 2)
        for ch in range(k):
            total = 0
            for dr in range(-1, 2):
                for dc in range(-1, 2):
                    total += image[r + dr, c + dc, ch]
            out[i, ch] = np.float32(total) / np.float32(9.0)


def median0(values: np.ndarray) -> np.ndarray:
    """``np.median(values, axis=0)`` (finite values) without its per-call overhead: many small arrays (the
    colours and widths here, float32, in one compiled call)."""
    values = np.asarray(values)
    if len(values) and values.dtype == np.float32 and values.ndim in (1, 2):
        columns = np.ascontiguousarray(values.reshape(len(values), -1))
        out = np.empty(columns.shape[1], np.float32)
        _column_medians(columns, out)
        return out[0] if values.ndim == 1 else out
    s = np.sort(values, axis=0)
    if not len(s):
        return np.full(s.shape[1:], np.nan)   # as np.median
    h = len(s) // 2
    return s[h] if len(s) % 2 else (s[h - 1] + s[h]) / 2


@njit(cache=True, nogil=True)
def _column_medians(values, out):
    """out[c] = the middle of the sorted column c, or the mean of the two middle values (their sum halved, in
    the arrays' float type, as numpy computes it)."""
    n, m = values.shape
    h = n // 2
    column = np.empty(n, values.dtype)
    for c in range(m):
        for i in range(n):
            column[i] = values[i, c]
        column.sort()
        out[c] = column[h] if n % 2 else (column[h - 1] + column[h]) / 2


@njit(cache=True, nogil=True)
def _run_medians(lab, bounds, out):
    """out[k] = ``median0`` of the a*, b* columns of ``lab`` rows bounds[k] to bounds[k + 1] (left unset for an
    empty run): every point set of a batch in one call (:func:`_column_medians`, the same numbers)."""
    for k in range(bounds.size - 1):
        if bounds[k + 1] > bounds[k]:
            _column_medians(lab[bounds[k]:bounds[k + 1], 1:], out[k])


def colour_sampler(image_bgr: np.ndarray):
    """``colour_of(points)``: median CIELAB (a*, b*) of the image (3x3 means) at (row, col) points;
    ``colour_of.at(points)`` gives the (n, 2) colours point by point."""
    def colour_of(points):
        return median0(_lab_ab(_sample(image_bgr, points)))

    def batch(point_sets):
        """Median colours of several point sets in one conversion (None for an empty set)."""
        sizes = [len(p) for p in point_sets]
        if not sum(sizes):
            return [None] * len(point_sets)
        lab = _lab(_sample(image_bgr, np.vstack([np.asarray(p).reshape(-1, 2) for p in point_sets])))
        medians = np.empty((len(sizes), 2), np.float32)
        _run_medians(np.ascontiguousarray(lab), np.cumsum([0] + sizes), medians)
        return [medians[k].copy() if n else None for k, n in enumerate(sizes)]

    colour_of.at = lambda points: _lab_ab(_sample(image_bgr, points))
    colour_of.lab_at = lambda points: _lab(_sample(image_bgr, points))
    colour_of.batch = batch
    return colour_of


def _disc(centre: np.ndarray, radius: float) -> np.ndarray:
    """(row, col) of the pixel offsets within ``radius`` of ``centre``, float."""
    dr, dc = _disc_offsets(float(radius))
    return np.stack([centre[0] + dr, centre[1] + dc], axis=1).astype(float)


@lru_cache(maxsize=32)
def _disc_offsets(radius: float):
    """Integer (row, col) offsets within ``radius`` (one crossing after another asks for the same disc)."""
    rr = max(1, int(np.ceil(radius)))
    dr, dc = np.mgrid[-rr:rr + 1, -rr:rr + 1]
    keep = dr ** 2 + dc ** 2 <= radius ** 2
    return dr[keep], dc[keep]


def _strand_points(points, first, last, centre, width_px):
    """The strand's own points for its colour: between 1.5 and 3.5 widths from the overlap (failing
    that, beyond 1.5 widths); empty if fewer than three."""
    reach = int(np.ceil(4 * width_px)) + 2
    points = points[max(0, first - reach):last + reach + 1]
    near = np.empty(len(points), np.bool_)
    count = _near_ring(np.ascontiguousarray(points, dtype=np.float64), float(centre[0]), float(centre[1]),
                       1.5 * width_px, 3.5 * width_px, near)
    return points[near] if count >= 3 else points[:0]


@njit(cache=True, nogil=True)
def _near_ring(points, centre_r, centre_c, inner, outer, near):
    """near = inner <= |p - centre| <= outer (np.hypot), or, if that holds for fewer than 3 points, inner <=
    |p - centre|; returns how many are near."""
    n = points.shape[0]
    d = np.empty(n)
    count = 0
    for i in range(n):
        d[i] = np.hypot(points[i, 0] - centre_r, points[i, 1] - centre_c)
        near[i] = d[i] >= inner and d[i] <= outer
        count += near[i]
    if count < 3:
        count = 0
        for i in range(n):
            near[i] = d[i] >= inner
            count += near[i]
    return count


def decide_crossings(image_bgr: np.ndarray, objects: list, width_px: float,
                     min_colour_separation: float = 12.0, min_edge_confidence: float = 0.05,
                     width_at=None, tangent_tolerance_rad: float = float(np.radians(8.0))) -> list:
    """Decisions for every pair of passes through the same crossing. ``objects`` are traced objects
    (``points``, ``passes`` as (crossing id, first, last) index ranges of their connectors);
    ``width_at(points)`` (optional) gives the rod width [px] at (row, col) points: each strand's own width
    (median over its colour points) then sets its occlusion-edge footprint, else ``width_px`` does."""
    by_crossing: dict[int, list] = {}
    for oid, obj in enumerate(objects):
        for cid, i0, i1 in obj.passes:
            by_crossing.setdefault(cid, []).append((oid, i0, i1))
    pairs = [(cid, passes[a], passes[b]) for cid, passes in sorted(by_crossing.items())
             for a in range(len(passes)) for b in range(a + 1, len(passes))]
    # overlap point of each pair, then the colours of all overlaps and strands in one conversion
    centres, point_sets = [], []
    for _, (oa, a0, a1), (ob, b0, b1) in pairs:
        ca = objects[oa].points[a0:a1 + 1]
        cb = objects[ob].points[b0:b1 + 1]
        d = np.hypot(ca[:, None, 0] - cb[None, :, 0], ca[:, None, 1] - cb[None, :, 1])
        ia, ib = np.unravel_index(np.argmin(d), d.shape)
        centre = 0.5 * (ca[ia] + cb[ib])
        centres.append(centre)
        point_sets += [_disc(centre, max(1.0, width_px / 3.0)),
                       _strand_points(objects[oa].points, a0, a1, centre, width_px),
                       _strand_points(objects[ob].points, b0, b1, centre, width_px)]
    colours = colour_sampler(image_bgr).batch(point_sets)
    decisions = [_decide_pair(cid, pa, pb, centre, *colours[3 * k:3 * k + 3], min_colour_separation)
                 for k, ((cid, pa, pb), centre) in enumerate(zip(pairs, centres))]
    bgr = np.ascontiguousarray(image_bgr)      # the probes convert the pixels they read to grey (no grey image)
    for k, (dec, (_, (oa, a0, a1), (ob, b0, b1))) in enumerate(zip(decisions, pairs)):
        if dec.over is not None:
            continue
        ta = _chord_direction(objects[oa].points[a0:a1 + 1])
        tb = _chord_direction(objects[ob].points[b0:b1 + 1])
        if ta is None or tb is None:
            continue
        wa, wb = (_strand_width(width_at, point_sets[3 * k + j], width_px) for j in (1, 2))
        signed = _edge_contrasts(bgr, dec.position, _perturbed_directions(ta, tb, tangent_tolerance_rad), wa, wb)
        if not np.all(np.isfinite(signed)):
            continue
        # the decision must hold for every direction within the tolerance: the confidence is the worst case
        conf = float(np.min(signed)) if signed[0] > 0 else float(-np.max(signed))
        if conf >= min_edge_confidence:
            dec.over, dec.confidence, dec.cue = (oa if signed[0] > 0 else ob), conf, 'edges'
    return decisions


def _strand_width(width_at, points, width_px):
    """A strand's own width: the median of ``width_at`` over its colour points, else ``width_px``."""
    if width_at is None or not len(points):
        return width_px
    w = float(median0(width_at(points)))
    return w if np.isfinite(w) and w > 0 else width_px


def _edge_contrasts(image_bgr, centre, directions, wa, wb):
    """(e_a - e_b) / (e_a + e_b) of the occlusion edge strengths of strands a and b (NaN if unknown) in the
    grey image of the (C-contiguous uint8) ``image_bgr``, for each (t_a, t_b) of ``directions`` (all probes in
    one compiled call, :func:`_edge_strength_kernel`)."""
    pairs = np.array(directions, dtype=np.float64).reshape(-1, 2, 2)      # (k, (t_a, t_b), (row, col))
    e = np.empty(2 * len(pairs))
    _edge_strengths_of_pairs(image_bgr, float(centre[0]), float(centre[1]), pairs, float(wa), float(wb), e)
    return [(ea - eb) / (ea + eb) if np.isfinite(ea) and np.isfinite(eb) and ea + eb > 0 else float('nan')
            for ea, eb in zip(e[0::2].tolist(), e[1::2].tolist())]


@njit(cache=True, nogil=True)
def _edge_strengths_of_pairs(bgr, centre_r, centre_c, pairs, wa, wb, out):
    """out[2 k], out[2 k + 1]: the edge strengths of strand a (direction pairs[k, 0], width wa) against b
    (pairs[k, 1], wb), and of b against a (:func:`_edge_strength_kernel`); the other strand's direction in
    the frame (t_self, n = (-t_self_c, t_self_r)) by numpy's (OpenBLAS's) 2-vector dot product, a fused
    multiply-add (:mod:`.fma`)."""
    n = 2 * pairs.shape[0]
    t_self = np.empty((n, 2))
    along, across = np.empty(n), np.empty(n)
    widths = np.empty((n, 2))
    for k in range(pairs.shape[0]):
        for m in range(2):
            i = 2 * k + m
            ts, to = pairs[k, m], pairs[k, 1 - m]
            t_self[i, 0], t_self[i, 1] = ts[0], ts[1]
            along[i] = fma64(to[1], ts[1], to[0] * ts[0])
            across[i] = fma64(to[1], ts[0], to[0] * -ts[1])
            widths[i, 0], widths[i, 1] = (wa, wb) if m == 0 else (wb, wa)
    _edge_strength_kernel(bgr, centre_r, centre_c, t_self, along, across, widths, out)


@njit(cache=True, nogil=True)
def _block_sum(a, lo, n):
    """numpy's pairwise sum of ``a[lo:lo + n]`` for n <= 128: sequential below 8, else eight running sums."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r = a[lo:lo + 8].copy()
    i = 8
    while i < n - (n % 8):
        for j in range(8):
            r[j] += a[lo + i + j]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True, nogil=True)
def _pairwise_sum(a, lo, n):
    """``np.add.reduce`` of ``a[lo:lo + n]`` in numpy's order (pairwise: blocks of up to 128 summed by
    :func:`_block_sum`, halves (a multiple of 8 first) above that), so that a compiled mean equals numpy's bit
    for bit. The halving is unrolled with an explicit stack: numba's cache cannot reload recursive functions."""
    if n <= 128:
        return _block_sum(a, lo, n)
    task_lo = np.empty(128, np.int64)
    task_n = np.empty(128, np.int64)
    task_combine = np.zeros(128, np.bool_)
    values = np.empty(128)
    n_tasks, n_values = 1, 0
    task_lo[0], task_n[0] = lo, n
    while n_tasks:
        n_tasks -= 1
        t_lo, t_n, combine = task_lo[n_tasks], task_n[n_tasks], task_combine[n_tasks]
        if combine:                              # both halves done: left + right
            n_values -= 1
            values[n_values - 1] = values[n_values - 1] + values[n_values]
        elif t_n <= 128:
            values[n_values] = _block_sum(a, t_lo, t_n)
            n_values += 1
        else:
            n2 = t_n // 2
            n2 -= n2 % 8
            # popped in reverse: the left half first, then the right half, then their sum
            task_lo[n_tasks], task_n[n_tasks], task_combine[n_tasks] = t_lo, t_n, True
            task_lo[n_tasks + 1], task_n[n_tasks + 1], task_combine[n_tasks + 1] = t_lo + n2, t_n - n2, False
            task_lo[n_tasks + 2], task_n[n_tasks + 2], task_combine[n_tasks + 2] = t_lo, n2, False
            n_tasks += 3
    return values[0]


@njit(cache=True, nogil=True)
def _grey(bgr, r, c):
    """``cv2.cvtColor(bgr, COLOR_BGR2GRAY)[r, c]``: (3735 B + 19235 G + 9798 R + 2^14) >> 15 (OpenCV's 8-bit
    fixed-point weights for 0.114, 0.587, 0.299; equal on all 2^24 colours, checked in the tests)."""
    return (3735 * np.int32(bgr[r, c, 0]) + 19235 * np.int32(bgr[r, c, 1]) + 9798 * np.int32(bgr[r, c, 2])
            + 16384) >> 15


@njit(cache=True, nogil=True)
def _edge_strength_kernel(bgr, centre_r, centre_c, t_self, along, across, widths, out):
    """:func:`occlusion_edge_strength` for each row i of ``t_self`` (with ``along``, ``across``: the other
    strand's direction in the frame (t_self, n), ``widths[i]``: (own, other) width), into ``out[i]``;
    the same points, bilinear samples and arithmetic (in numpy's order) as :func:`_occlusion_probes` and
    :func:`_edge_strengths`, without building the probe arrays."""
    h, w = bgr.shape[:2]
    for i in range(t_self.shape[0]):
        out[i] = np.nan
        tr, tc = t_self[i, 0], t_self[i, 1]
        nr, nc = -tc, tr
        sin = abs(across[i])
        if sin < 0.2:
            continue
        width, other = widths[i, 0], widths[i, 1]
        half = 0.5 * other / sin
        n_u = max(3, int(np.ceil(1.4 * half)) + 1)
        start, stop = -0.7 * half, 0.7 * half
        step = (stop - start) / (n_u - 1)
        u = np.empty(n_u)
        for j in range(n_u):
            u[j] = j * step + start
        u[n_u - 1] = stop
        lo = np.floor(max(1.0, 0.25 * width - 1.0))
        n_off = int(np.ceil(np.ceil(0.75 * width + 1.0) + 1.0 - lo))
        # every probe point first: the set is void if any runs off the image
        vals = np.empty((2, n_off, 2, n_u))          # (side, offset, +- 0.75 n, u)
        ok = True
        for side in range(2):
            for j in range(n_off):
                o = lo + j if side == 0 else -(lo + j)
                u_o = o * along[i] / across[i]
                base_r = centre_r + o * nr
                base_c = centre_c + o * nc
                for m in range(2):
                    sr = 0.75 * nr
                    sc = 0.75 * nc
                    for k in range(n_u):
                        s = u_o + u[k]
                        pr = base_r + s * tr
                        pc = base_c + s * tc
                        if m == 0:
                            pr, pc = pr + sr, pc + sc
                        else:
                            pr, pc = pr - sr, pc - sc
                        if pr < 0 or pc < 0 or pr > h - 1 or pc > w - 1:
                            ok = False
                            break
                        r0 = min(max(int(np.floor(pr)), 0), h - 2)
                        c0 = min(max(int(np.floor(pc)), 0), w - 2)
                        fr, fc = pr - r0, pc - c0
                        vals[side, j, m, k] = ((1 - fr) * (1 - fc) * np.float64(_grey(bgr, r0, c0))
                                               + (1 - fr) * fc * np.float64(_grey(bgr, r0, c0 + 1))
                                               + fr * (1 - fc) * np.float64(_grey(bgr, r0 + 1, c0))
                                               + fr * fc * np.float64(_grey(bgr, r0 + 1, c0 + 1)))
                    if not ok:
                        break
                if not ok:
                    break
            if not ok:
                break
        if not ok:
            continue
        total = 0.0
        deriv = np.empty(n_u)
        for side in range(2):
            strongest = -np.inf
            for j in range(n_off):
                for k in range(n_u):
                    deriv[k] = abs(vals[side, j, 0, k] - vals[side, j, 1, k]) / 1.5
                strongest = max(strongest, _pairwise_sum(deriv, 0, n_u) / n_u)
            total = strongest if side == 0 else total + strongest
        out[i] = total


def _rotate(t, angle_rad):
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([c * t[0] - s * t[1], s * t[0] + c * t[1]])


def _perturbed_directions(ta, tb, tolerance_rad):
    """The strands' directions as measured, then each turned by -+ ``tolerance_rad`` (the measured first)."""
    out = [(ta, tb)]
    if tolerance_rad > 0:
        for sgn in (-1.0, 1.0):
            out += [(_rotate(ta, sgn * tolerance_rad), tb), (ta, _rotate(tb, sgn * tolerance_rad))]
    return out


def _chord_direction(points):
    """Unit direction of a strand through a crossing: the chord of its pass (anchor to anchor, both outside
    the overlap; on a curved rod parallel to the tangent halfway), None if too short."""
    if len(points) < 3:
        return None
    d = points[-1] - points[0]
    n = float(np.linalg.norm(d))
    return d / n if n > 0 else None


def occlusion_edge_strength(grey: np.ndarray, centre, t_self, t_other, width_px: float,
                            other_width_px: float | None = None) -> float:
    """How strongly strand ``self`` (width ``width_px``) shows its own boundary inside the overlap with
    strand ``other`` (width ``other_width_px``, default the same).

    The upper rod's silhouette runs on across the crossing (against the lower rod, with the shading at its
    rim and the shadow it casts), while the lower rod's boundary stops where the upper rod covers it. For
    lines parallel to ``t_self`` at offsets o from 0.25 w_self - 1 to 0.75 w_self + 1 px on each side (about
    its own boundary, where the upper strand's silhouette runs on; farther out, the other rod's shading and
    the ramp of the upper rod make edges of their own), within the other strand's
    footprint on that line (|u - u_o| <= 0.35 w_other / sin(angle), u along ``t_self``, u_o = o cot(angle)
    where the other strand's centre line crosses it: at an oblique crossing the footprint slides along
    the line with the offset, and a window fixed at u = 0 would see the lower rod's own boundary beside
    the upper rod), the mean absolute derivative of ``grey`` across ``t_self`` is taken; the strongest line
    on each side counts, and the two sides are added. NaN where the crossing is too shallow or runs off
    the image."""
    return _edge_strengths(grey, [_occlusion_probes(grey.shape, centre, t_self, t_other, width_px,
                                                    other_width_px)])[0]


def _occlusion_probes(shape, centre, t_self, t_other, width_px, other_width_px=None):
    """The points where :func:`occlusion_edge_strength` samples an image of ``shape``: (side, +- 0.75 n,
    offset, u, 2); None where the crossing is too shallow or the points run off the image."""
    t_self = np.asarray(t_self, float)
    t_other = np.asarray(t_other, float)
    other_width_px = width_px if other_width_px is None else other_width_px
    n = np.array([-t_self[1], t_self[0]])
    along, across = float(t_other @ t_self), float(t_other @ n)
    sin = abs(across)
    if sin < 0.2:
        return None
    half = 0.5 * other_width_px / sin
    u = np.linspace(-0.7 * half, 0.7 * half, max(3, int(np.ceil(1.4 * half)) + 1))
    offsets = np.arange(np.floor(max(1.0, 0.25 * width_px - 1.0)), np.ceil(0.75 * width_px + 1.0) + 1.0)
    h, w = shape
    # both sides (+n, -n), both probe lines (+- 0.75 n): (side, +-, offset, u)
    o = np.stack([offsets, -offsets])
    u_o = o * along / across                     # the other strand's centre line on the line at offset o
    pts = (np.asarray(centre, float)[None, None, None, :] + o[:, :, None, None] * n
           + (u_o[:, :, None] + u)[..., None] * t_self)
    probes = np.stack([pts + 0.75 * n, pts - 0.75 * n], axis=1)
    if probes.min() < 0 or probes[..., 0].max() > h - 1 or probes[..., 1].max() > w - 1:
        return None
    return probes


def _edge_strengths(grey, probe_sets):
    """:func:`occlusion_edge_strength` of each of ``probe_sets`` (from :func:`_occlusion_probes`; NaN for
    None), with one bilinear gather for all."""
    valid = [p.reshape(-1, 2) for p in probe_sets if p is not None]
    values = _bilinear(grey, np.concatenate(valid)) if valid else None
    out, start = [], 0
    for p in probe_sets:
        if p is None:
            out.append(float('nan'))
            continue
        v = values[start:start + p.size // 2].reshape(p.shape[:-1])
        start += p.size // 2
        # |derivative| across t_self on each line: the strongest line per side counts, both sides added
        deriv = np.abs(v[:, 0] - v[:, 1]) / 1.5
        strongest = deriv.mean(axis=2).max(axis=1)
        out.append(float(strongest[0]) + float(strongest[1]))
    return out


def _bilinear(image, pts):
    r, c = pts[..., 0], pts[..., 1]
    r0 = np.minimum(np.maximum(np.floor(r).astype(np.intp), 0), image.shape[0] - 2)
    c0 = np.minimum(np.maximum(np.floor(c).astype(np.intp), 0), image.shape[1] - 2)
    fr, fc = r - r0, c - c0
    return ((1 - fr) * (1 - fc) * image[r0, c0] + (1 - fr) * fc * image[r0, c0 + 1]
            + fr * (1 - fc) * image[r0 + 1, c0] + fr * fc * image[r0 + 1, c0 + 1])


def _decide_pair(cid, pa, pb, centre, overlap, col_a, col_b, min_sep):
    (oa, a0, a1), (ob, b0, b1) = pa, pb
    spans = ((a0, a1), (b0, b1))
    if col_a is None or col_b is None:
        return CrossingDecision(cid, centre, (oa, ob), None, 0.0, 0.0, spans)
    sep = float(np.linalg.norm(col_a - col_b))
    if sep < min_sep:
        return CrossingDecision(cid, centre, (oa, ob), None, 0.0, sep, spans)
    da = float(np.linalg.norm(overlap - col_a))
    db = float(np.linalg.norm(overlap - col_b))
    over = oa if da <= db else ob
    conf = float(np.clip(abs(db - da) / sep, 0.0, 1.0))
    return CrossingDecision(cid, centre, (oa, ob), over, conf, sep, spans, 'colour')
