"""Evaluation of perceived centrelines: instance masks, instance DICE, centreline error.

* :func:`render_instances` draws each object's centreline with its width into a label image (1..K, in
  object order): a pixel belongs to the object when its centre lies within half the width of the
  centreline (exact to ~0.01 px; OpenCV's filled circles would add about one pixel to the width). At each
  crossing with a decided order the upper object is drawn again near the crossing.
* :func:`instance_dice` matches predicted to ground-truth instances one-to-one (Hungarian, maximal
  DICE) and reports the pooled instance DICE 2 sum|P_k & G_k| / (sum|P| + sum|G|) (a pixel agrees only if
  it carries the matched instance) and the mean per-instance DICE (unmatched instances count 0).
* :func:`centreline_rms` is the RMS distance from a perceived path to a reference curve and back.
Units: pixels.
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment
from numba import njit
from scipy.spatial import cKDTree

from rod_deploy.perception.centreline import resample


def tube_pixels(points: np.ndarray, radius_px: float, shape) -> tuple:
    """(rows, cols) of the pixels whose centres lie within ``radius_px`` of the polyline ``points``."""
    if len(points) == 0:
        return np.zeros(0, int), np.zeros(0, int)
    dense = resample(points, 0.25) if len(points) > 1 else np.asarray(points, float)
    cand = np.zeros(shape[:2], dtype=np.uint8)
    thick = int(np.ceil(2 * radius_px)) + 3
    cv2.polylines(cand, [np.round(dense[:, ::-1]).astype(np.int32)], False, 1, thick)
    for r, c in np.round(dense[[0, -1]]).astype(int):
        cv2.circle(cand, (int(c), int(r)), int(np.ceil(radius_px)) + 2, 1, -1)
    rows, cols = np.nonzero(cand)
    d, _ = cKDTree(dense).query(np.stack([rows, cols], axis=1), distance_upper_bound=radius_px + 1.0)
    keep = d <= radius_px
    return rows[keep], cols[keep]


def _draw_tube(label: np.ndarray, points: np.ndarray, radius_px: float, value: int):
    rows, cols = tube_pixels(points, radius_px, label.shape)
    label[rows, cols] = value


def render_instances(objects, crossings, shape) -> np.ndarray:
    """uint8 label image (0 background, k + 1 for object k) of objects with ``points`` and ``width_px``."""
    label = np.zeros(shape[:2], dtype=np.uint8)
    dense = [resample(o.points, 0.5) for o in objects]
    for k, o in enumerate(objects):
        _draw_tube(label, o.points, 0.5 * o.width_px, k + 1)
    for c in crossings:
        if c.over is None:
            continue
        a, b = c.objects
        if a == b:
            continue
        reach = max(objects[a].width_px, objects[b].width_px) + 2.0
        pts = dense[c.over]
        near = np.hypot(pts[:, 0] - c.position[0], pts[:, 1] - c.position[1]) <= reach
        _draw_tube(label, pts[near], 0.5 * objects[c.over].width_px, c.over + 1)
    return label


def instance_dice(pred: np.ndarray, gt: np.ndarray):
    """(pooled instance DICE, mean per-instance DICE, matching {gt label: pred label})."""
    pred = np.asarray(pred).astype(np.int64)
    gt = np.asarray(gt).astype(np.int64)
    kp, kg = int(pred.max(initial=0)), int(gt.max(initial=0))
    conf = np.bincount((gt * (kp + 1) + pred).ravel(), minlength=(kg + 1) * (kp + 1)).reshape(kg + 1, kp + 1)
    inter = conf[1:, 1:]
    g_area = conf[1:, :].sum(axis=1)
    p_area = conf[:, 1:].sum(axis=0)
    if kp == 0 or kg == 0:
        return 0.0, 0.0, {}
    dice = 2.0 * inter / np.maximum(g_area[:, None] + p_area[None, :], 1)
    rows, cols = linear_sum_assignment(-dice)
    pooled = 2.0 * inter[rows, cols].sum() / max(g_area.sum() + p_area.sum(), 1)
    mean = dice[rows, cols].sum() / max(kp, kg)
    return float(pooled), float(mean), {int(r) + 1: int(c) + 1 for r, c in zip(rows, cols)}


def _point_to_polyline(points: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """Distance from each point to the polyline ``curve`` (brute force over all segments, compiled)."""
    out = np.empty(len(points))
    _polyline_distances(np.ascontiguousarray(points, dtype=np.float64),
                        np.ascontiguousarray(curve, dtype=np.float64), out)
    return out


@njit(cache=True, nogil=True)
def _polyline_distances(points, curve, out):
    """``out[i]``: the distance from ``points[i]`` to the nearest segment of ``curve`` (the closest point on a
    segment a + t (b - a), t clipped to [0, 1], |b - a|^2 at least 1e-12)."""
    for i in range(points.shape[0]):
        pr, pc = points[i, 0], points[i, 1]
        best = np.inf
        for k in range(curve.shape[0] - 1):
            ar, ac = curve[k, 0], curve[k, 1]
            dr, dc = curve[k + 1, 0] - ar, curve[k + 1, 1] - ac
            t = ((pr - ar) * dr + (pc - ac) * dc) / max(dr * dr + dc * dc, 1e-12)
            t = min(max(t, 0.0), 1.0)
            er, ec = pr - (ar + t * dr), pc - (ac + t * dc)
            d2 = er * er + ec * ec
            if d2 < best:
                best = d2
        out[i] = np.sqrt(best)


def centreline_rms(path: np.ndarray, reference: np.ndarray, step_px: float = 0.5) -> dict:
    """Distances between a perceived path and a reference curve, both (n, 2) [px]:
    ``rms_px`` over both directions (path to curve and curve to path, so missing or extra pieces count),
    ``to_curve_rms_px``, ``from_curve_rms_px``, ``max_px``, and ``end_error_px`` (largest distance between
    matching end points, the better of the two directions)."""
    p = resample(np.asarray(path, float), step_px)
    r = resample(np.asarray(reference, float), step_px)
    d1 = _point_to_polyline(p, r)
    d2 = _point_to_polyline(r, p)
    both = np.concatenate([d1, d2])
    e_fwd = max(np.linalg.norm(p[0] - r[0]), np.linalg.norm(p[-1] - r[-1]))
    e_rev = max(np.linalg.norm(p[0] - r[-1]), np.linalg.norm(p[-1] - r[0]))
    return {'rms_px': float(np.sqrt(np.mean(both ** 2))),
            'to_curve_rms_px': float(np.sqrt(np.mean(d1 ** 2))),
            'from_curve_rms_px': float(np.sqrt(np.mean(d2 ** 2))),
            'max_px': float(both.max()),
            'end_error_px': float(min(e_fwd, e_rev))}


def arc_length_error(path: np.ndarray, reference: np.ndarray, n: int = 50) -> dict:
    """Paper Eq. 17 in pixels: both curves resampled to ``n`` points by arc length, mean and standard
    deviation of the point distances, the better of the two directions of ``path``."""
    def at_n(c):
        c = np.asarray(c, float)
        s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(c, axis=0).T))])
        t = np.linspace(0, s[-1], n)
        return np.stack([np.interp(t, s, c[:, 0]), np.interp(t, s, c[:, 1])], axis=1)
    r = at_n(reference)
    best = None
    for p in (at_n(path), at_n(np.asarray(path)[::-1])):
        d = np.linalg.norm(p - r, axis=1)
        if best is None or d.mean() < best[0]:
            best = (float(d.mean()), float(d.std()))
    return {'mean_px': best[0], 'std_px': best[1]}
