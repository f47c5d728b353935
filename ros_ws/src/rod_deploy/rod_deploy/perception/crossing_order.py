"""Over/under order at crossings, decided from colour where the two strands differ in colour.

Where two strands cross, the pixels of the overlap show the upper strand. For every pair of strands
through a crossing, the overlap point is where their connectors come closest; the colour there (median
over a disc of a third of the stroke width) is compared, in CIELAB chromaticity (a*, b*: insensitive to
shading and glare), with each strand's own colour (median along the strand between 1.5 and 3.5 stroke
widths from the overlap, on both sides). The strand whose own colour is nearer is on top. Colours are
3x3 means, which keeps JPEG noise out. When the two strands' colours differ by less than
``min_colour_separation`` (e.g. a rod crossing itself) the order is left undecided: a single-colour photo
does not show it reliably.
Confidence = (d_under - d_over) / separation, in [0, 1] for a clean decision.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass
class CrossingDecision:
    crossing: int                    # crossing cluster id
    position: np.ndarray             # (row, col) [px] of the overlap
    objects: tuple                   # (object a, object b); equal for a self-crossing
    over: int | None                 # object id on top, None if undecided
    confidence: float                # 0 when undecided
    separation: float                # colour difference of the two strands [CIELAB a*b* units]
    spans: tuple = ()                # ((first, last) index range of the pass of a, same for b)


def _lab(bgr_pixels: np.ndarray) -> np.ndarray:
    """(n, 3) CIELAB (L*, a*, b*) of BGR pixels."""
    px = np.asarray(bgr_pixels, dtype=np.float32).reshape(-1, 1, 3) / 255.0
    return cv2.cvtColor(px, cv2.COLOR_BGR2Lab).reshape(-1, 3)


def _lab_ab(bgr_pixels: np.ndarray) -> np.ndarray:
    return _lab(bgr_pixels)[:, 1:]


def _sample(image: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Mean colour over the 3x3 pixels around each (row, col) point (cheaper than blurring the image)."""
    h, w = image.shape[:2]
    points = np.asarray(points).reshape(-1, 2)
    r = np.minimum(np.maximum(np.round(points[:, 0]).astype(np.intp), 1), max(h - 2, 1))
    c = np.minimum(np.maximum(np.round(points[:, 1]).astype(np.intp), 1), max(w - 2, 1))
    if h < 3 or w < 3:
        return image[np.minimum(r, h - 1), np.minimum(c, w - 1)].astype(np.float32)
    flat = image.reshape(-1, image.shape[2])
    window = np.array([-w - 1, -w, -w + 1, -1, 0, 1, w - 1, w, w + 1], dtype=np.intp)
    # one gather of the nine neighbours, (9, n, channels); sums of integers (<= 9 * 255) are exact in float32
    return flat[window[:, None] + (r * w + c)[None, :]].astype(np.float32).sum(axis=0) / 9.0


def median0(values: np.ndarray) -> np.ndarray:
    """``np.median(values, axis=0)`` (finite values) without its per-call overhead: many small arrays."""
    s = np.sort(values, axis=0)
    h = len(s) // 2
    return s[h] if len(s) % 2 else (s[h - 1] + s[h]) / 2


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
        ab = _lab_ab(_sample(image_bgr, np.vstack([np.asarray(p).reshape(-1, 2) for p in point_sets])))
        out, start = [], 0
        for n in sizes:
            out.append(median0(ab[start:start + n]) if n else None)
            start += n
        return out

    colour_of.at = lambda points: _lab_ab(_sample(image_bgr, points))
    colour_of.lab_at = lambda points: _lab(_sample(image_bgr, points))
    colour_of.batch = batch
    return colour_of


def _disc(centre: np.ndarray, radius: float) -> np.ndarray:
    rr = max(1, int(np.ceil(radius)))
    dr, dc = np.mgrid[-rr:rr + 1, -rr:rr + 1]
    keep = dr ** 2 + dc ** 2 <= radius ** 2
    return np.stack([centre[0] + dr[keep], centre[1] + dc[keep]], axis=1).astype(float)


def _strand_points(points, first, last, centre, width_px):
    """The strand's own points for its colour: between 1.5 and 3.5 widths from the overlap (failing
    that, beyond 1.5 widths); empty if fewer than three."""
    reach = int(np.ceil(4 * width_px)) + 2
    points = points[max(0, first - reach):last + reach + 1]
    d = np.hypot(points[:, 0] - centre[0], points[:, 1] - centre[1])
    near = (d >= 1.5 * width_px) & (d <= 3.5 * width_px)
    if near.sum() < 3:
        near = d >= 1.5 * width_px
    return points[near] if near.sum() >= 3 else points[:0]


def decide_crossings(image_bgr: np.ndarray, objects: list, width_px: float,
                     min_colour_separation: float = 12.0) -> list:
    """Decisions for every pair of passes through the same crossing. ``objects`` are traced objects
    (``points``, ``passes`` as (crossing id, first, last) index ranges of their connectors)."""
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
    return [_decide_pair(cid, pa, pb, centre, *colours[3 * k:3 * k + 3], min_colour_separation)
            for k, ((cid, pa, pb), centre) in enumerate(zip(pairs, centres))]


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
    return CrossingDecision(cid, centre, (oa, ob), over, conf, sep, spans)
