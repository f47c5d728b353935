"""Small self loops whose hole the mask closes (a rod looping over itself tightly, the hole blurred shut).

The mask then holds a solid blob where the loop is, its skeleton runs straight through the blob (no
crossing is found) and the traced path cuts the loop short. The blob gives itself away by its width: on a
rod's path the mask's width 2 d - 1 (d the distance to the background) is the rod's width, at a crossing of
two rods of one width at most sqrt(2) times it, while a filled loop of radius R is a disc of radius
R + w / 2 (width 2 R + w >= 2 w for any loop at all). Inside the blob the loop's centreline is the blob's
iso-distance contour at the rod's half width (d = (w + 1) / 2, the same d as on the rod's own centreline).
The path is re-traced: the lead-in up to where it reaches that contour, once round the contour from the
point nearest to both leads (the loop's crossing), in the sense that continues the lead-in's direction and
arrives along the lead-out's, then the lead-out. That contour rounds off the loop's neck, where the rod
crosses itself: where the leads, drawn on into the blob, meet (:func:`_neck`), the loop is traced through
that crossing instead, running straight on from it along the leads' directions to the contour.
Units: pixels, points (row, col).
"""
from __future__ import annotations

import cv2
import numpy as np

from rod_deploy.perception import centreline as cl
from rod_deploy.perception.skeleton_graph import END, JUNCTION, remove_node_if_isolated

MIN_BLOB_FACTOR = 2.0    # a filled loop: the mask at least this many rod widths wide on the path
MARGIN_PX = 1.5          # the contour level above the rod's own centreline distance (keeps the leads out)


def trace_filled_loop(points: np.ndarray, dist: np.ndarray, other_points=(), passes_px=(),
                      min_blob_factor: float = MIN_BLOB_FACTOR, margin_px: float = MARGIN_PX):
    """``points`` (an open path, ~1 px steps) with a filled loop traced round its blob, or unchanged.

    ``dist``: the mask's distance map (to the background, full resolution). ``other_points``: the other
    objects' paths (a blob they pass through is a crossing, not a loop); ``passes_px``: (row, col) points
    where this path passes a crossing (a loop the skeleton already found, or a crossing: left alone).
    One loop per call (the widest blob)."""
    n = len(points)
    if n < 8:
        return points
    d = cl.lookup(dist, points).astype(float)
    w = max(2.0 * float(cl._median(d)) - 1.0, 1.0)          # the rod's width in the mask
    k_max = int(np.argmax(d))
    if 2.0 * d[k_max] - 1.0 < min_blob_factor * w:
        return points
    level = 0.5 * (w + 1.0) + margin_px
    # the blob's core: the component of {d >= level} under the widest point of the path
    r0 = max(int(points[k_max, 0] - 4 * d[k_max] - 4), 0)
    c0 = max(int(points[k_max, 1] - 4 * d[k_max] - 4), 0)
    r1 = min(int(points[k_max, 0] + 4 * d[k_max] + 5), dist.shape[0])
    c1 = min(int(points[k_max, 1] + 4 * d[k_max] + 5), dist.shape[1])
    core = (dist[r0:r1, c0:c1] >= level).astype(np.uint8)
    _, labels = cv2.connectedComponents(core, connectivity=8)
    pr, pc = int(round(points[k_max, 0])) - r0, int(round(points[k_max, 1])) - c0
    lab = labels[min(max(pr, 0), core.shape[0] - 1), min(max(pc, 0), core.shape[1] - 1)]
    if lab == 0:
        return points
    blob = (labels == lab).astype(np.uint8)
    if blob[0, :].any() or blob[-1, :].any() or blob[:, 0].any() or blob[:, -1].any():
        return points                                       # not a compact blob (a long wide stretch)
    contours, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return points
    ring = max(contours, key=len)[:, 0, ::-1].astype(float) + (r0, c0)     # (row, col)
    if len(ring) < 8:
        return points
    centre = ring.mean(axis=0)
    rho = np.hypot(*(ring - centre).T)
    radius = float(cl._median(rho))
    ring = centre + (ring - centre) * (1.0 + margin_px / np.maximum(rho, 1.0))[:, None]   # back out to the level
    ring = ring[rho <= 1.25 * radius]       # without the spikes where the leads join the blob (its concave corners)
    if len(ring) < 8:
        return points
    # a loop is convex: its hull (a notch where the hole shows through the mask is bridged), 1 px steps
    hull = cv2.convexHull(ring[:, ::-1].astype(np.float32))[:, 0, ::-1].astype(float)
    ring = cl.resample(np.vstack([hull, hull[:1]]), 1.0)[:-1]
    if radius < 0.5 * w:
        return points
    inside = np.hypot(*(points - centre).T) <= radius + 0.5 * w + 1.0
    for q in list(passes_px) + list(other_points):
        q = np.atleast_2d(q)
        if len(q) and (np.hypot(*(q - centre).T) <= radius + 0.5 * w).any():
            return points                                   # a crossing with another path: not a loop
    idx = np.flatnonzero(cl.lookup(blob, points - (r0, c0)) > 0)
    idx = idx[(points[idx, 0] >= r0) & (points[idx, 0] < r1) & (points[idx, 1] >= c0) & (points[idx, 1] < c1)]
    if len(idx) == 0:
        return points
    a, b = int(idx[0]), int(idx[-1])
    lead = max(int(round(w)), 3)
    if a < lead or b > n - 1 - lead or inside[0] or inside[-1]:
        return points                                       # the loop is at a path end: leave it
    neck = _neck(points, a, b, w, ring)
    if neck is not None:
        return neck
    t_in = points[a] - points[a - lead]
    t_out = points[b + lead] - points[b]
    k = int(np.argmin(np.hypot(*(ring - points[a]).T) + np.hypot(*(ring - points[b]).T)))
    m = len(ring)
    best = None
    for s in (1, -1):
        loop = ring[(k + s * np.arange(m + 1)) % m]
        dep = loop[min(lead, m - 1)] - loop[0]
        arr = loop[-1] - loop[-1 - min(lead, m - 1)]
        score = (np.dot(dep, t_in) / (np.linalg.norm(dep) * np.linalg.norm(t_in) + 1e-9)
                 + np.dot(arr, t_out) / (np.linalg.norm(arr) * np.linalg.norm(t_out) + 1e-9))
        if best is None or score > best[0]:
            best = (score, loop)
    out = np.vstack([points[:a + 1], best[1], points[b:]])
    out = cl.resample(out, 1.0)
    return cl.smooth(out, 1.5, False)


def prune_blob_spurs(graph, dist: np.ndarray, width_px: float, spur_px: float,
                     min_blob_factor: float = MIN_BLOB_FACTOR) -> int:
    """Remove the dead-end branches of the skeleton that end inside a filled loop's blob: a branch from a
    junction where the mask is at least ``min_blob_factor`` rod widths wide (2 d - 1, ``dist`` the mask's
    distance map at the graph's scale; both ``width_px``, the typical rod width there, and the rod's own
    width, 2 d - 1 along the junction's other branches from 2 d to 6 d out, past the blob) to a free end less than the
    junction's own d + ``spur_px`` away along it. Thinning leaves such a branch towards the blob's bulge
    (the far side of the loop); it is as long as the blob is wide, so the plain spur rule (``spur_px``)
    keeps it, and at its junction it takes the lead-out's or lead-in's place (the straighter pairing),
    cutting the rod in two at the loop. A rod's own end leaves the blob (more than d + ``spur_px``
    long); at a junction on a rod's path, or at a crossing of two rods (d below w), nothing changes. A
    junction keeps at least two branches. Returns the number of branches removed."""
    removed = 0
    for eid, e in graph.live_edges():
        if e.closed or e.u == e.v:
            continue
        ku, kv = graph.nodes[e.u].kind, graph.nodes[e.v].kind
        if (ku == END) == (kv == END) or JUNCTION not in (ku, kv):
            continue
        junction, end = (e.v, e.u) if ku == END else (e.u, e.v)
        node = graph.nodes[junction]
        if len(node.edges) < 3:
            continue
        d = float(cl.lookup(dist, node.position[None, :])[0])
        if 2.0 * d - 1.0 < min_blob_factor * width_px or e.length_px() >= d + spur_px:
            continue
        # the rod's own width: on the junction's other branches, past the junction's blob
        skip = int(np.ceil(2.0 * d))
        arms = [graph.branch_points(x, side)[skip:skip + int(np.ceil(4.0 * d))] for x, side in node.edges
                if x != eid]
        arms = [a for a in arms if len(a)]
        if not arms or 2.0 * d - 1.0 < min_blob_factor * (2.0 * float(cl._median(cl.lookup(dist, np.vstack(arms))))
                                                          - 1.0):
            continue
        graph.remove_edge(eid)
        remove_node_if_isolated(graph, end)
        removed += 1
    return removed


def _lead_curve(points, end, step, w, fit_factor, reach_factor):
    """Points (1 px steps) of the parabola (in arc length) fitted to a lead's points from ``fit_factor`` w to
    w before the blob (``end``: the first (``step`` -1) or last (+1) index in the blob; the skeleton bends
    into the blob over about a width), extrapolated from w before the blob on towards it for
    ``reach_factor`` w; None if the lead is shorter. A lead curves on into its loop: a straight line drawn on
    from its last stretch misses the crossing by pixels."""
    far, near = end + step * int(round(fit_factor * w)), end + step * int(round(w))
    if not (0 <= far < len(points) and 0 <= near < len(points)):
        return None
    q = points[far:near - step:-step]                    # ordered towards the blob
    s = cl.arc_length(q)
    if s[-1] <= 0:
        return None
    coef = np.polyfit(s - s[-1], q, 2)                  # (3, 2): row and column as quadratics in s
    t = np.arange(0.0, reach_factor * w + 1.0, 1.0)
    return np.stack([np.polyval(coef[:, 0], t), np.polyval(coef[:, 1], t)], axis=1)


def _ray_hits(origin, t, ring):
    """(segment index, distance, point) where the ray ``origin`` + s ``t`` (s > 0) first meets the closed polygon
    ``ring`` (segment k from ring[k] to ring[k + 1]), or None."""
    a = ring
    b = np.roll(ring, -1, axis=0)
    e = b - a
    den = t[0] * e[:, 1] - t[1] * e[:, 0]
    with np.errstate(divide='ignore', invalid='ignore'):
        r = a - origin
        s = (r[:, 0] * e[:, 1] - r[:, 1] * e[:, 0]) / den
        u = (r[:, 0] * t[1] - r[:, 1] * t[0]) / den
    ok = (np.abs(den) > 1e-12) & (s > 0) & (u >= 0) & (u <= 1)
    if not ok.any():
        return None
    k = int(np.flatnonzero(ok)[np.argmin(s[ok])])
    return k, float(s[k]), origin + s[k] * t


def _neck(points, a, b, w, ring, fit_factor=4.0, min_angle_deg=20.0, max_reach_factor=3.0,
          max_straight_factor=1.5):
    """The loop traced from its crossing (the neck): a rod looping over itself crosses its own lead-in where
    the lead-in and the lead-out, drawn on into the blob (:func:`_lead_curve`), meet (X), and runs on through
    X (the loop leaves X along the lead-in's direction and arrives along the lead-out's); the blob's centreline
    contour ``ring`` rounds that corner off. The path: the lead-in up to w before the blob, drawn on to X,
    on along its tangent at X to where that line meets the ring, round the ring to where the lead-out's tangent
    line (backwards from X) meets it, X, the lead-out drawn back from X to w past the blob. None (use the ring
    alone) when the leads are shorter than ``fit_factor`` w, do not meet within ``max_reach_factor`` w, cross
    at less than ``min_angle_deg``, or the contour lies more than ``max_straight_factor`` w from X along
    either straight run (a loop whose head is wider than its neck curves away from the straight run)."""
    c_in = _lead_curve(points, a, -1, w, fit_factor, max_reach_factor)
    c_out = _lead_curve(points, b, 1, w, fit_factor, max_reach_factor)
    if c_in is None or c_out is None:
        return None
    gap = np.hypot(c_in[:, None, 0] - c_out[None, :, 0], c_in[:, None, 1] - c_out[None, :, 1])
    i, j = np.unravel_index(int(np.argmin(gap)), gap.shape)
    if gap[i, j] > 1.5 or i in (0, len(c_in) - 1) or j in (0, len(c_out) - 1):
        return None                                     # the leads do not cross within reach
    x = 0.5 * (c_in[i] + c_out[j])
    t_in = c_in[i + 1] - c_in[i - 1]
    t_out = c_out[j - 1] - c_out[j + 1]                  # along the path: away from the blob
    t_in, t_out = t_in / np.hypot(*t_in), t_out / np.hypot(*t_out)
    if abs(t_in[0] * t_out[1] - t_in[1] * t_out[0]) < np.sin(np.radians(min_angle_deg)):
        return None
    hit_in, hit_out = _ray_hits(x, t_in, ring), _ray_hits(x, -t_out, ring)
    if hit_in is None or hit_out is None or max(hit_in[1], hit_out[1]) > max_straight_factor * w:
        return None                        # a loop wider than its neck bends away from the straight run
    (k_in, _, q_in), (k_out, _, q_out) = hit_in, hit_out
    m = len(ring)
    # round the ring from q_in in the sense that continues the lead-in's direction
    step = 1 if np.dot(ring[(k_in + 1) % m] - ring[k_in], t_in) >= 0 else -1
    if step == 1:
        arc = ring[(k_in + 1 + np.arange((k_out - k_in) % m)) % m]
    else:
        arc = ring[(k_in - np.arange((k_in - k_out) % m)) % m]
    if len(arc) < 0.25 * m:                # a sliver of the ring: not this loop's shape
        return None
    near_in, near_out = a - int(round(w)), b + int(round(w))
    out = np.vstack([points[:near_in + 1], c_in[1:i], x, q_in, arc, q_out, x, c_out[j - 1:0:-1],
                     points[near_out:]])
    out = cl.resample(out, 1.0)
    return cl.smooth(out, 1.5, False)
