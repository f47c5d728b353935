"""Traversal of the paired skeleton graph into one ordered centreline per object.

Each object starts at a free end (or, for a closed loop, anywhere) and follows its chain; at a crossing it
leaves its branch at the anchor, follows a cubic Hermite connector (tangents from the branches) to the
anchor of the paired branch and continues there, until it reaches an end, an unpaired branch or its own
start (closed loop). The shared chains inside a crossing (internal edges) belong to no object. Every pass
through a crossing is recorded, so that the crossing's over/under order can be decided afterwards.
:func:`join_gaps` then joins ends that face each other across a short gap: a rod passing under another
often shows a dark seam (shadow, edge) on one side of the upper rod, which cuts it in the mask.
Units: pixels, points (row, col).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from rod_deploy.perception.bending_energy_pairing import Crossing, branch_geometry, colours_differ
from rod_deploy.perception.centreline import arc_length, path_length
from rod_deploy.perception.crossing_order import _column_medians, median0
from rod_deploy.perception.nearest import nearest_distances
from rod_deploy.perception.skeleton_graph import END, SkeletonGraph


@dataclass
class TracedObject:
    """An ordered centreline; ``passes`` lists (crossing id, first, last) index ranges of its connectors."""
    points: np.ndarray
    closed: bool = False
    passes: list = field(default_factory=list)

    def length_px(self) -> float:
        return path_length(self.points)


def hermite_connector(p0, t0, p1, t1, step_px: float = 1.0) -> np.ndarray:
    """Points of the cubic Hermite curve from ``p0`` (direction ``t0``) to ``p1`` (direction ``t1``), tangent
    magnitudes equal to the chord length; both end points included."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = float(np.linalg.norm(p1 - p0))
    n = max(2, int(np.ceil(d / step_px)) + 1)
    t0, t1 = np.asarray(t0, float), np.asarray(t1, float)
    s = np.arange(n, dtype=np.float64) * (1.0 / (n - 1))      # np.linspace(0, 1, n)'s numbers, without its overhead
    s[-1] = 1.0
    s = s[:, None]
    if p0.shape == p1.shape == t0.shape == t1.shape == (2,):
        # numpy's s ** 3 (its vectorised pow is not libm's), the rest compiled
        return _hermite(s[:, 0], (s ** 3)[:, 0], p0, d * t0, p1, d * t1)
    h00 = 2 * s ** 3 - 3 * s ** 2 + 1
    h10 = s ** 3 - 2 * s ** 2 + s
    h01 = -2 * s ** 3 + 3 * s ** 2
    h11 = s ** 3 - s ** 2
    return h00 * p0 + h10 * (d * t0) + h01 * p1 + h11 * (d * t1)


@njit(cache=True, nogil=True)
def _hermite(s, s3, p0, m0, p1, m1):
    """h00 p0 + h10 m0 + h01 p1 + h11 m1 at the parameters ``s`` (``s3`` = s ** 3), in numpy's order: the
    basis as 2 s3 - 3 s^2 + 1, s3 - 2 s^2 + s, -2 s3 + 3 s^2, s3 - s^2 (s^2 = s s), sums left to right."""
    out = np.empty((s.size, 2))
    for k in range(s.size):
        s2 = s[k] * s[k]
        h00 = 2 * s3[k] - 3 * s2 + 1
        h10 = s3[k] - 2 * s2 + s[k]
        h01 = -2 * s3[k] + 3 * s2
        h11 = s3[k] - s2
        for c in range(2):
            out[k, c] = h00 * p0[c] + h10 * m0[c] + h01 * p1[c] + h11 * m1[c]
    return out


def trace_objects(graph: SkeletonGraph, crossings: list) -> list:
    """Ordered centrelines of all objects (see module docstring)."""
    # (edge, side) -> (crossing id, branch index) for every branch at a crossing
    at_crossing = {}
    internal = set()
    for cid, c in enumerate(crossings):
        internal.update(c.internal_edges)
        for bi, b in enumerate(c.branches):
            at_crossing[(b.edge, b.side)] = (cid, bi)
    partner = {}
    for cid, c in enumerate(crossings):
        for i, j in c.pairs:
            partner[(cid, i)] = j
            partner[(cid, j)] = i

    used = set()
    objects = []

    def anchor_index(eid, side):
        hit = at_crossing.get((eid, side))
        if hit is None:
            return 0
        return crossings[hit[0]].branches[hit[1]].anchor_index

    def walk(start_edge, start_side, closed_possible):
        pieces, passes = [], []
        eid, entry = start_edge, start_side
        n_points = 0
        closed = False
        while True:
            used.add(eid)
            pts = graph.branch_points(eid, entry)         # ordered from the entry end
            a = anchor_index(eid, entry)
            b = len(pts) - 1 - anchor_index(eid, 1 - entry)
            if b < a:                                      # anchors cross on a very short chain
                a = b = (a + b) // 2
            seg = pts[a:b + 1]
            pieces.append(seg)
            n_points += len(seg)
            exit_side = 1 - entry
            hit = at_crossing.get((eid, exit_side))
            if hit is None:
                break
            cid, bi = hit
            bj = partner.get((cid, bi))
            if bj is None:
                break
            c: Crossing = crossings[cid]
            nxt = c.branches[bj]
            conn = hermite_connector(c.branches[bi].anchor, c.branches[bi].tangent, nxt.anchor, -nxt.tangent)
            inner = conn[1:-1]
            passes.append((cid, n_points - 1, n_points + len(inner)))
            pieces.append(inner)
            n_points += len(inner)
            if closed_possible and (nxt.edge, nxt.side) == (start_edge, start_side):
                closed = True
                break
            if nxt.edge in used:                           # should not happen: a pairing reused an edge
                break
            eid, entry = nxt.edge, nxt.side
        points = np.vstack([p for p in pieces if len(p)])
        if closed:
            points = np.vstack([points, points[:1]])
        return TracedObject(points, closed, passes)

    # open objects from free ends, then from unpaired branches at crossings
    starts = []
    for eid, e in graph.live_edges():
        if eid in internal or e.closed:
            continue
        for side, nid in ((0, e.u), (1, e.v)):
            if graph.nodes[nid].kind == END:
                starts.append((0, eid, side))
            elif (eid, side) in at_crossing:
                cid, bi = at_crossing[(eid, side)]
                if (cid, bi) not in partner:
                    starts.append((1, eid, side))
    for _, eid, side in sorted(starts):
        if eid not in used:
            objects.append(walk(eid, side, closed_possible=False))
    # closed loops: plain closed chains, and cycles through crossings
    for eid, e in graph.live_edges():
        if eid in used or eid in internal:
            continue
        if e.closed:
            used.add(eid)
            objects.append(TracedObject(e.points.copy(), True, []))
        else:
            objects.append(walk(eid, 0, closed_possible=True))
    return objects


@dataclass
class GapJoin:
    """Two object ends joined across a gap (an object passing under another one, whose shadow or edge
    cuts it, or a pen stroke with a skip)."""
    crossing: int            # id given to the gap, after the skeleton crossings
    centre: np.ndarray       # (row, col) [px], middle of the connector
    length_px: float


def _end_geometry(points: np.ndarray, last: bool, skip_px: float, fit_px: float):
    """Anchor index (counted from that end), anchor point and outward unit tangent at one end."""
    q = points[::-1] if last else points
    i0, t = branch_geometry(q, skip_px, fit_px)
    return i0, q[i0], t


def _reindex_passes(passes, n, reverse, offset, keep_lo, keep_hi):
    out = []
    for cid, a, b in passes:
        if reverse:
            a, b = n - 1 - b, n - 1 - a
        if a < keep_lo or b > keep_hi:
            continue
        out.append((cid, a - keep_lo + offset, b - keep_lo + offset))
    return out


def join_gaps(objects: list, width_px: float, first_crossing_id: int, max_gap_factor: float = 3.0,
              max_turn_rad: float = np.radians(30.0), colour_of=None, min_colour_separation: float = 12.0,
              covered=None, max_hidden_factor: float = 20.0, max_hidden_turn_rad: float = np.radians(60.0),
              width_of=None):
    """Join pairs of open ends of different objects that face each other across a short gap.

    An end qualifies when the gap (between the ends' anchors, ``0.75 w + 2`` px back from the ends, since a
    trace ending at a junction bends into it) is at most ``max_gap_factor`` w and both end tangents point
    along the gap within ``max_turn_rad`` and (if ``colour_of`` is given) their colours agree; the
    straightest joins go first. With ``covered(points)`` (True where the image shows a rod) a longer
    stretch, up to ``max_hidden_factor`` w with turns up to ``max_hidden_turn_rad``, also qualifies when
    the connector runs over rods but for at most ``max_gap_factor`` w (1 px points): a rod hidden under
    another one along a length (an end lying along it, a shallow crossing, where the upper rod's shadow
    may cut the lower one too), whose two visible parts are of one colour. A joined object
    records the gap as a pass, and the object passing closest to the gap's middle (if any, within w)
    records a pass there too, so that the over/under decision covers the occlusion. With ``width_of(points)``
    (an object's own width [px]), a wider object's ends use its own width w' (the larger of the two ends'
    for the gap limits): a rod wider than w bends into the junction where it was cut over a longer
    stretch, and the rod above it cuts a longer gap.
    Returns (objects, gap joins)."""
    cos_max = np.cos(max_turn_rad)
    hidden = covered is not None and max_hidden_factor > 0
    cos_hidden = np.cos(max_hidden_turn_rad)
    objects = list(objects)
    joins = []
    end_cache = {}        # id(object) -> (object, its two ends); the object's points never change here
    while True:
        new_ends, stretches = [], []
        for o in objects:
            if id(o) in end_cache or o.closed or o.length_px() < 3 * (0.75 * width_px + 2.0):
                continue
            end_cache[id(o)] = (o, [])
            w_o = width_px if width_of is None else max(width_px, float(width_of(o.points)))
            skip, fit = min(0.75 * w_o + 2.0, o.length_px() / 3), 1.5 * w_o + 2.0
            for last in (False, True):
                i0, p, t = _end_geometry(o.points, last, skip, fit)
                q = o.points[::-1] if last else o.points
                stretches.append(q[i0:i0 + int(np.ceil(fit)) + 1])
                new_ends.append([last, i0, p, t, None, w_o])
                end_cache[id(o)][1].append(new_ends[-1])
        if colour_of is not None and new_ends:
            colours = (colour_of.batch(stretches) if hasattr(colour_of, 'batch')
                       else [colour_of(q) for q in stretches])
            for e, c in zip(new_ends, colours):
                e[4] = c
        ends = [[oid] + e for oid, o in enumerate(objects) if id(o) in end_cache for e in end_cache[id(o)][1]]
        best = None
        for i in range(len(ends)):
            for j in range(i + 1, len(ends)):
                oa, la, ia, pa, ta, ca_, w_a = ends[i]
                ob, lb, ib, pb, tb, cb_, w_b = ends[j]
                if oa == ob or colours_differ(ca_, cb_, min_colour_separation):
                    continue
                w_ab = max(w_a, w_b)
                max_gap = (max_gap_factor + 1.5) * w_ab + 4.0
                max_hidden = (max_hidden_factor + 1.5) * w_ab + 4.0 if hidden else 0.0
                chord = pb - pa
                d = float(np.linalg.norm(chord))
                if d > max(max_gap, max_hidden) or d < 1e-6:
                    continue
                u = chord / d
                ca, cb = float(np.dot(ta, u)), float(np.dot(-tb, u))
                if d > max_gap or ca < cos_max or cb < cos_max:
                    if (ca < cos_hidden or cb < cos_hidden or d > max_hidden or ca_ is None or cb_ is None
                            or np.count_nonzero(~covered(hermite_connector(pa, ta, pb, -tb)))
                            > max_gap_factor * w_ab):
                        continue
                cost = (1 - ca) + (1 - cb) + 0.01 * d / width_px
                if best is None or cost < best[0]:
                    best = (cost, ends[i], ends[j], d)
        if best is None:
            return objects, joins
        _, (oa, la, ia, pa, ta, _, _), (ob, lb, ib, pb, tb, _, _), d = best
        a, b = objects[oa], objects[ob]
        na, nb = len(a.points), len(b.points)
        pa_pts = a.points if la else a.points[::-1]
        keep_a = na - ia
        head = pa_pts[:keep_a]
        pb_pts = b.points[::-1] if lb else b.points
        tail = pb_pts[ib:]
        conn = hermite_connector(head[-1], ta, tail[0], -tb)[1:-1]
        cid = first_crossing_id + len(joins)
        passes = _reindex_passes(a.passes, na, not la, 0, 0, keep_a - 1)
        passes.append((cid, keep_a - 1, keep_a + len(conn)))
        passes += _reindex_passes(b.passes, nb, lb, keep_a + len(conn), ib, nb - 1)
        joined = TracedObject(np.vstack([head, conn, tail]), False, passes)
        centre = 0.5 * (head[-1] + tail[0])
        joins.append(GapJoin(cid, centre, d))
        objects = [o for k, o in enumerate(objects) if k not in (oa, ob)] + [joined]
        _mark_occluder(objects, len(objects) - 1, cid, centre, width_px)


def _mark_occluder(objects, joined_id, cid, centre, width_px):
    """Give the object passing closest to ``centre`` (within w) a pass through gap ``cid``."""
    best = None
    for oid, o in enumerate(objects):
        d = np.hypot(o.points[:, 0] - centre[0], o.points[:, 1] - centre[1])
        if oid == joined_id:        # the joined object itself may pass over its own gap elsewhere
            for c, a, b in o.passes:
                if c == cid:
                    d[max(0, a - int(2 * width_px)):b + int(2 * width_px) + 1] = np.inf
        k = int(np.argmin(d))
        if d[k] <= width_px and (best is None or d[k] < best[0]):
            best = (d[k], oid, k)
    if best is None:
        return
    _, oid, k = best
    half = int(np.ceil(width_px))
    o = objects[oid]
    o.passes.append((cid, max(0, k - half), min(len(o.points) - 1, k + half)))


def split_at_colour_changes(objects: list, colours_at, width_px: float, min_separation: float,
                            min_length_px: float, max_splits: int = 4) -> list:
    """Cut objects where their colour changes for good: two rods of different colours touching end to
    end, or end to side, leave one skeleton chain with no junction between them.

    Colours (``colours_at(points)`` -> (n, 2) CIELAB a*b*) are taken every half width along the path,
    leaving out the passes through crossings, where the upper strand's colour shows. A cut goes where the
    mean colours of the ``4 w`` before and after differ most, if by more than 2.5 ``min_separation``,
    both pieces are at least ``min_length_px`` long and each is of one colour over 80 % of its length.
    Then the ends of every open object are trimmed where they are not of its colour
    (:func:`trim_foreign_ends`)."""
    out = []
    queue = list(objects)
    splits = 0
    while queue:
        o = queue.pop(0)
        cut = None if (o.closed or splits >= max_splits) else _colour_cut(o, colours_at, width_px, min_separation,
                                                                           min_length_px)
        if cut is None:
            out.append(o)
            continue
        splits += 1
        a = TracedObject(o.points[:cut + 1].copy(), False, [p for p in o.passes if p[2] <= cut])
        b = TracedObject(o.points[cut:].copy(), False,
                         [(c, i0 - cut, i1 - cut) for c, i0, i1 in o.passes if i1 > cut and i0 >= cut])
        queue += [a, b]
    return [trim_foreign_ends(o, colours_at, width_px, min_separation) for o in out]


def trim_foreign_ends(o, colours_at, width_px: float, min_separation: float, reach_factor: float = 4.0,
                      foreign_factor: float = 2.5, min_foreign_fraction: float = 0.5):
    """Cut off an open object's end where it runs on past the rod into something of another colour (a dark
    texture blob of the table or the rod's own shadow, merged with the rod's end in the mask).

    Within ``reach_factor`` w of each end (and before its first crossing), points are foreign where their
    CIELAB a*b* (``colours_at``) is farther than ``foreign_factor`` ``min_separation`` from the object's
    median colour; the end is cut just inside the farthest foreign point beyond which at least
    ``min_foreign_fraction`` of the stretch to the end is foreign."""
    if o.closed or len(o.points) < 8:
        return o
    pts = o.points
    s = arc_length(pts)
    reach = reach_factor * width_px
    if s[-1] < 4 * reach:
        return o
    first_pass = min((i0 for _, i0, _ in o.passes), default=len(pts))
    last_pass = max((i1 for _, _, i1 in o.passes), default=-1)
    samples, n_body, n_head = _end_samples(s, reach, max(1, int(0.5 * width_px)), first_pass, last_pass)
    col = np.ascontiguousarray(colours_at(pts[samples]), dtype=np.float32)
    lo, hi = _foreign_ends(col, samples, n_body, n_head, len(pts), foreign_factor * min_separation,
                           min_foreign_fraction)
    if lo == 0 and hi == len(pts) - 1:
        return o
    return TracedObject(pts[lo:hi + 1].copy(), False, [(c, i0 - lo, i1 - lo) for c, i0, i1 in o.passes])


@njit(cache=True, nogil=True)
def _end_samples(s, reach, step, first_pass, last_pass):
    """(indices, n_body, n_head) for :func:`trim_foreign_ends`: every ``step``-th point of the body (arc
    length ``s`` more than ``reach`` from both ends), then the head's points (within ``reach`` of the start,
    before the first pass), then the tail's (within ``reach`` of the end, after the last pass)."""
    n = s.size
    end = s[n - 1]
    out = np.empty(n, np.int64)
    m = 0
    seen = 0
    for i in range(n):
        if s[i] > reach and s[i] < end - reach:
            if seen % step == 0:
                out[m] = i
                m += 1
            seen += 1
    n_body = m
    for i in range(min(n, first_pass)):
        if s[i] <= reach:
            out[m] = i
            m += 1
    n_head = m - n_body
    for i in range(max(last_pass + 1, 0), n):
        if s[i] >= end - reach:
            out[m] = i
            m += 1
    return out[:m].copy(), n_body, n_head


@njit(cache=True, nogil=True)
def _foreign_ends(col, samples, n_body, n_head, n, limit, min_fraction):
    """(lo, hi): the kept index range of :func:`trim_foreign_ends` from the float32 colours ``col`` at
    :func:`_end_samples`: foreign where farther than ``limit`` (float32) from the body's median colour; from
    each end inwards, the farthest foreign sample where the foreign fraction so far is at least
    ``min_fraction`` is cut off with everything outside it."""
    lo, hi = 0, n - 1
    if n_body == 0:                              # no own colour (numpy's median: nan, nothing foreign)
        return lo, hi
    median = np.empty(2, np.float32)
    _column_medians(col[:n_body], median)
    bound = np.float32(limit)
    foreign = 0
    for k in range(n_head):                      # head: from the start inwards
        x0, x1 = col[n_body + k, 0] - median[0], col[n_body + k, 1] - median[1]
        if np.sqrt(x0 * x0 + x1 * x1) > bound:
            foreign += 1
            if foreign / (k + 1) >= min_fraction:
                lo = samples[n_body + k] + 1
    n_tail = samples.size - n_body - n_head
    foreign = 0
    for k in range(n_tail):                      # tail: from the end inwards
        i = samples.size - 1 - k
        x0, x1 = col[i, 0] - median[0], col[i, 1] - median[1]
        if np.sqrt(x0 * x0 + x1 * x1) > bound:
            foreign += 1
            if foreign / (k + 1) >= min_fraction:
                hi = samples[i] - 1
    return lo, hi


def _colour_cut(o, colours_at, width_px, min_separation, min_length_px):
    pts = o.points
    if len(pts) < 8:
        return None
    s = arc_length(pts)
    if s[-1] < 2 * min_length_px:
        return None
    step = max(1.0, 0.5 * width_px)
    idx = np.searchsorted(s, np.arange(0.0, s[-1], step)).clip(0, len(pts) - 1)
    idx = idx[np.concatenate([[True], idx[1:] != idx[:-1]])]      # np.unique of the sorted indices
    keep = np.ones(len(idx), dtype=bool)
    for _, i0, i1 in o.passes:                      # crossings show the upper strand's colour
        keep &= ~((s[idx] >= s[i0] - width_px) & (s[idx] <= s[i1] + width_px))
    idx = idx[keep]
    win = max(3, int(round(4 * width_px / step)))
    if len(idx) < 2 * win:
        return None
    col = np.ascontiguousarray(colours_at(pts[idx]), dtype=np.float32)
    cut = _best_colour_cut(col, np.ascontiguousarray(idx, dtype=np.int64), s, win, float(min_length_px),
                           2.5 * min_separation, 1.5 * min_separation)
    return None if cut < 0 else cut


@njit(cache=True, nogil=True)
def _best_colour_cut(col, idx, s, win, min_length_px, min_step, max_spread):
    """The cut of :func:`_colour_cut` from the float32 colours ``col`` at the samples ``idx`` (arc lengths
    ``s``), or -1: the mean colours of the ``win`` samples before and after each sample (running float32
    sums, as np.cumsum, differenced in float64) differ most (Euclidean) where both pieces are at least
    ``min_length_px`` long; the cut lies between the last sample before and the first after, if that
    difference is at least ``min_step`` and each piece's colours lie within ``max_spread`` of its median
    (float32, as numpy compares them) at 80 % of its samples at least."""
    n = col.shape[0]
    cc = np.zeros((n + 1, 2))
    run0, run1 = np.float32(0.0), np.float32(0.0)
    for i in range(n):
        run0 += col[i, 0]
        run1 += col[i, 1]
        cc[i + 1, 0], cc[i + 1, 1] = run0, run1
    best_j, best_d, best_cut = -1, -1.0, -1
    for k in range(win, n - win + 1):
        d0 = (cc[k, 0] - cc[k - win, 0]) / win - (cc[k + win, 0] - cc[k, 0]) / win
        d1 = (cc[k, 1] - cc[k - win, 1]) / win - (cc[k + win, 1] - cc[k, 1]) / win
        d = np.sqrt(d0 * d0 + d1 * d1)
        cut_at = (idx[k - 1] + idx[k]) // 2
        if s[cut_at] >= min_length_px and s[s.size - 1] - s[cut_at] >= min_length_px and d > best_d:
            best_j, best_d, best_cut = k, d, cut_at
    if best_j < 0 or best_d < min_step:
        return -1
    # each piece must be one colour along (almost) all its length: not a tangle of several rods
    limit = np.float32(max_spread)
    median = np.empty(2, np.float32)
    for lo, hi in ((0, best_j), (best_j, n)):
        _column_medians(col[lo:hi], median)
        inside = 0
        for i in range(lo, hi):
            x0, x1 = col[i, 0] - median[0], col[i, 1] - median[1]
            inside += np.sqrt(x0 * x0 + x1 * x1) < limit
        if inside / (hi - lo) < 0.8:
            return -1
    return best_cut


def drop_shadow_strands(objects: list, lab_at, half_width_at, min_colour_separation: float,
                        beside_factor: float = 2.5, min_beside_fraction: float = 0.5, min_inside_fraction: float = 0.8,
                        min_darker: float = 20.0, max_shadow_factor: float = 12.0) -> list:
    """Drop objects that are the shadow of a rod, or a sliver of one, lying along a longer object.

    ``half_width_at(points)`` gives the object half-width there (the mask's distance to background on the
    centreline), so h = its median along the longer object. A shorter object is dropped when at least
    ``min_inside_fraction`` of its points lie within h + 1 px of the longer one's path (a strand inside
    that rod: shading split its mask lengthwise), or when it is no longer than ``max_shadow_factor`` h (a
    shadow cast by the raised part of a rod at a crossing, not a rod lying alongside), at least
    ``min_beside_fraction`` of it lies within ``beside_factor`` h and it is darker by ``min_darker`` (CIELAB L*) or of clearly another colour (a*b*
    farther apart than ``min_colour_separation``): on a light table a rod's shadow is foreground too and,
    where it is wide enough, leaves its own skeleton beside the rod. ``lab_at(points)`` -> (n, 3) CIELAB."""
    if len(objects) < 2:
        return objects
    order = sorted(range(len(objects)), key=lambda i: -objects[i].length_px())
    sub = {i: objects[i].points[::max(1, len(objects[i].points) // 60)] for i in order}
    colours = {i: median0(lab_at(sub[i])) for i in order}
    half_widths = {}                             # per object, when first needed
    drop = set()
    for rank, i in enumerate(order):
        pts = objects[i].points
        for j in order[:rank]:
            if j in drop:
                continue
            if j not in half_widths:
                half_widths[j] = float(median0(half_width_at(sub[j])))
            h = half_widths[j]
            d = nearest_distances(objects[j].points, pts, beside_factor * h + 1.0)     # inf beyond the bound
            if np.mean(d <= h + 1.0) >= min_inside_fraction:
                drop.add(i)
                break
            if np.mean(np.isfinite(d)) < min_beside_fraction or objects[i].length_px() > max_shadow_factor * h:
                continue
            ci, cj = colours[i], colours[j]
            if ci[0] < cj[0] - min_darker or np.linalg.norm(ci[1:] - cj[1:]) > min_colour_separation:
                drop.add(i)
                break
    return [o for k, o in enumerate(objects) if k not in drop]


def unpaired_branch_ends(crossings: list, to_full=lambda p: p, scale: float = 1.0) -> list:
    """(anchor, crossing centre, widest rod width) of every branch left unpaired at a crossing, in the
    coordinates ``to_full`` maps to (``scale``: full-resolution pixels per processing pixel): an object that
    starts there is a rod whose end lies against or on another rod (a T in the skeleton)."""
    out = []
    for c in crossings:
        for i in c.unpaired():
            out.append((to_full(c.branches[i].anchor), to_full(c.centre), scale * c.width_px))
    return out


def place_abutting_end(points: np.ndarray, anchor, centre, colours_at, width_px: float, other_width_px: float,
                       min_separation: float, foreign_factor: float = 2.5, step_px: float = 0.5):
    """The end of an open path (``points[-1]``) that starts at an unpaired branch of a crossing (its rod's
    end lies against the side of another rod, or on top of it), placed by colour: the skeleton stops it at
    the branch anchor, short of the end, or the evidence-based end placement runs it on through the other
    rod. Along the path's tangent (over 1.5 widths) from half a width before the anchor, up to its own width
    + ``other_width_px`` + 2 px past the crossing centre (its end may lie on the other rod, its end cap
    beyond it), the first of two successive samples whose CIELAB a*b* is farther than ``foreign_factor``
    ``min_separation`` from the path's own colour (its median between 2 and 6 widths from the anchor) is
    the rod's boundary. Past the crossing centre the rod lies on top and its end cap shows: the end goes
    half a width inside the boundary, on that ray. Before it, the other rod's colour begins and the rod's
    end is hidden under it, somewhere between its near and far edges: the end goes half a width before the
    centre (the middle of that range). Where no colour boundary shows (rods of one colour) the path is
    returned as it is. Units: pixels, (row, col)."""
    pts = np.asarray(points, float)
    if len(pts) < 4:
        return pts
    s = arc_length(pts)
    ia = int(np.argmin(np.hypot(pts[:, 0] - anchor[0], pts[:, 1] - anchor[1])))
    sa = s[ia]
    body = (s >= sa - 6.0 * width_px) & (s <= sa - 2.0 * width_px)
    if body.sum() < 3:
        return pts
    own = median0(colours_at(pts[body]))
    sq = sa - 0.5 * width_px
    if sq <= 0.0:
        return pts
    q = np.array([np.interp(sq, s, pts[:, 0]), np.interp(sq, s, pts[:, 1])])
    sb = max(sq - 1.5 * width_px, 0.0)
    t = q - np.array([np.interp(sb, s, pts[:, 0]), np.interp(sb, s, pts[:, 1])])
    nt = float(np.linalg.norm(t))
    if nt < 1e-6:
        return pts
    t /= nt
    dc = float(np.dot(np.asarray(centre, float) - q, t))
    steps = np.arange(0.0, max(dc, 0.0) + other_width_px + width_px + 2.0 + 1e-9, step_px)
    ray = q[None, :] + steps[:, None] * t[None, :]
    foreign = np.linalg.norm(colours_at(ray) - own, axis=1) > foreign_factor * min_separation
    run = foreign[:-1] & foreign[1:]
    if not run.any():
        return pts
    k = int(np.argmax(run))
    end = max(max(steps[k] - 0.5 * step_px, dc) - 0.5 * width_px, 0.0)
    extra = np.arange(1.0, end + 1e-9, 1.0)
    if extra.size == 0 or extra[-1] < end - 1e-6:
        extra = np.append(extra, end)
    extra = extra[extra > 1e-6]
    return np.vstack([pts[s < sq], q[None, :], q[None, :] + extra[:, None] * t[None, :]])
