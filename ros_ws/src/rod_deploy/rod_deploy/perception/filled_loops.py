"""Small self loops whose hole the mask closes (a rod looping over itself tightly, the hole blurred shut).

The mask then holds a solid blob where the loop is, its skeleton runs straight through the blob (no
crossing is found) and the traced path cuts the loop short. The blob gives itself away by its width: on a
rod's path the mask's width 2 d - 1 (d the distance to the background) is the rod's width, at a crossing of
two rods of one width at most sqrt(2) times it, while a filled loop of radius R is a disc of radius
R + w / 2 (width 2 R + w >= 2 w for any loop at all). Inside the blob the loop's centreline is the blob's
iso-distance contour at the rod's half width (d = (w + 1) / 2, the same d as on the rod's own centreline).
The path is re-traced: the lead-in up to where it reaches that contour, once round the contour from the
point nearest to both leads (the loop's crossing), in the sense that continues the lead-in's direction and
arrives along the lead-out's, then the lead-out. Units: pixels, points (row, col).
"""
from __future__ import annotations

import cv2
import numpy as np

from rod_deploy.perception import centreline as cl

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
