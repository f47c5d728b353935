"""Overlay for people: the ordered paths drawn on the (dimmed) photo.

Each object gets its own colour, a ring at its start with its id, arrows along its direction of travel
and a square at its end. At a crossing with a decided order the upper object is drawn again over the
lower one and a ring marks the crossing (white: decided from colour; yellow with its confidence in
percent: decided from occlusion edges); an undecided crossing gets a '?'. A legend
lists every object's length and width and explains the marks; with a metric mapping a scale bar is drawn.
"""
from __future__ import annotations

import cv2
import numpy as np

from rod_deploy.perception.centreline import arc_length

PALETTE = [(0, 215, 255), (255, 128, 0), (60, 220, 60), (255, 0, 255), (0, 0, 255), (255, 255, 0),
           (128, 0, 255), (0, 255, 160), (255, 160, 160), (160, 160, 255)]   # BGR


def _pts(points: np.ndarray, shift: int = 4) -> np.ndarray:
    return np.round(points[:, ::-1] * (1 << shift)).astype(np.int32)


def draw_overlay(image_bgr: np.ndarray, objects: list, crossings: list, metres_per_px: float | None = None,
                 dim: float = 0.55) -> np.ndarray:
    """BGR overlay image. ``objects`` have ``points`` (row, col) [px], ``width_px`` and ``closed``;
    ``crossings`` have ``position``, ``objects`` and ``over`` (None: undecided)."""
    img = image_bgr
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    out = (img.astype(np.float32) * dim).astype(np.uint8)
    h, w = out.shape[:2]
    unit = max(1, int(round(min(h, w) / 450)))
    thick = unit + 1
    font_scale = 0.45 * unit

    def draw_path(points, colour, t):
        if len(points) >= 2:
            cv2.polylines(out, [_pts(points)], False, colour, t, cv2.LINE_AA, 4)

    for k, o in enumerate(objects):
        colour = PALETTE[k % len(PALETTE)]
        draw_path(o.points, colour, thick)
    # upper strands over lower ones at decided crossings
    for c in crossings:
        if c.over is None or c.objects[0] == c.objects[1]:
            continue
        o = objects[c.over]
        near = np.hypot(o.points[:, 0] - c.position[0], o.points[:, 1] - c.position[1]) <= 1.5 * o.width_px + 4
        idx = np.flatnonzero(near)
        if idx.size >= 2:
            for run in np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1):
                draw_path(o.points[run], (0, 0, 0), thick + 2 * unit)
                draw_path(o.points[run], PALETTE[c.over % len(PALETTE)], thick)
    for k, o in enumerate(objects):
        colour = PALETTE[k % len(PALETTE)]
        s = arc_length(o.points)
        if len(o.points) >= 2 and s[-1] > 0:
            step = max(40.0 * unit, s[-1] / 10.0)
            for s0 in np.arange(step / 2, s[-1] - 2.0, step):
                i = int(np.searchsorted(s, s0))
                j = int(np.searchsorted(s, min(s0 + 12.0 * unit, s[-1])))
                if j > i:
                    a, b = o.points[i], o.points[j]
                    cv2.arrowedLine(out, (int(a[1]), int(a[0])), (int(b[1]), int(b[0])), colour, thick,
                                    cv2.LINE_AA, tipLength=0.6)
        p0, p1 = o.points[0], o.points[-1]
        cv2.circle(out, (int(p0[1]), int(p0[0])), 5 * unit, colour, thick, cv2.LINE_AA)
        cv2.putText(out, str(k), (int(p0[1]) + 6 * unit, int(p0[0]) - 6 * unit), cv2.FONT_HERSHEY_SIMPLEX,
                    font_scale * 1.3, colour, unit + 1, cv2.LINE_AA)
        if not o.closed:
            q = 4 * unit
            cv2.rectangle(out, (int(p1[1]) - q, int(p1[0]) - q), (int(p1[1]) + q, int(p1[0]) + q), colour, -1)
    for c in crossings:
        centre = (int(c.position[1]), int(c.position[0]))
        if c.over is None:
            cv2.putText(out, '?', (centre[0] + 4 * unit, centre[1] - 4 * unit), cv2.FONT_HERSHEY_SIMPLEX,
                        font_scale * 1.3, (255, 255, 255), unit + 1, cv2.LINE_AA)
        elif getattr(c, 'cue', 'colour') == 'edges':
            cv2.circle(out, centre, 3 * unit, (0, 230, 255), unit, cv2.LINE_AA)
            cv2.putText(out, f'{100 * c.confidence:.0f}', (centre[0] + 4 * unit, centre[1] - 4 * unit),
                        cv2.FONT_HERSHEY_SIMPLEX, font_scale, (0, 230, 255), unit, cv2.LINE_AA)
        else:
            cv2.circle(out, centre, 3 * unit, (255, 255, 255), unit, cv2.LINE_AA)
    # legend
    y = 18 * unit
    for k, o in enumerate(objects):
        length = arc_length(o.points)[-1] if len(o.points) > 1 else 0.0
        text = f'{k}: {length:.0f} px'
        if metres_per_px:
            text += f' ({length * metres_per_px:.3f} m)'
        text += f', width {o.width_px:.1f} px' + (', closed' if o.closed else '')
        colour = PALETTE[k % len(PALETTE)]
        cv2.rectangle(out, (8 * unit, y - 9 * unit), (18 * unit, y + unit), colour, -1)
        cv2.putText(out, text, (22 * unit, y), cv2.FONT_HERSHEY_SIMPLEX, font_scale, (255, 255, 255), unit,
                    cv2.LINE_AA)
        y += 16 * unit
    n_dec = sum(1 for c in crossings if c.over is not None)
    n_edges = sum(1 for c in crossings if c.over is not None and getattr(c, 'cue', 'colour') == 'edges')
    lines = ['ring + id: start of a path, square: its end, arrows: its direction',
             f'crossings: {len(crossings)}; over/under from colour: white ring ({n_dec - n_edges}), from',
             f'  occlusion edges: yellow ring + confidence % ({n_edges}); upper path drawn on top;',
             f'  ?: order undecided ({len(crossings) - n_dec})']
    for text in lines:
        cv2.putText(out, text, (8 * unit, y), cv2.FONT_HERSHEY_SIMPLEX, font_scale, (255, 255, 255), unit,
                    cv2.LINE_AA)
        y += 16 * unit
    if metres_per_px:
        draw_scale_bar(out, metres_per_px, unit, font_scale)
    return out


def scale_bar_length_m(metres_per_px: float, image_width_px: int) -> float:
    """A round length (1, 2 or 5 x 10^k m) close to a fifth of the image width."""
    target = image_width_px * metres_per_px / 5.0
    exponent = np.floor(np.log10(target))
    candidates = [m * 10.0 ** exponent for m in (1.0, 2.0, 5.0, 10.0)]
    return float(min(candidates, key=lambda c: abs(np.log(c / target))))


def draw_scale_bar(out: np.ndarray, metres_per_px: float, unit: int = 1, font_scale: float = 0.45):
    """A white bar with its length in metres (cm or mm when shorter) at the bottom left of ``out`` (in place)."""
    h, w = out.shape[:2]
    length_m = scale_bar_length_m(metres_per_px, w)
    length_px = int(round(length_m / metres_per_px))
    x0, y0 = 10 * unit, h - 12 * unit
    cv2.rectangle(out, (x0 - 4 * unit, y0 - 22 * unit), (x0 + length_px + 4 * unit, y0 + 6 * unit), (0, 0, 0), -1)
    cv2.rectangle(out, (x0, y0 - 3 * unit), (x0 + length_px, y0), (255, 255, 255), -1)
    if length_m >= 1.0:
        label = f'{length_m:g} m'
    elif length_m >= 0.01:
        label = f'{100 * length_m:g} cm'
    else:
        label = f'{1000 * length_m:g} mm'
    cv2.putText(out, label, (x0, y0 - 8 * unit), cv2.FONT_HERSHEY_SIMPLEX, font_scale, (255, 255, 255), unit,
                cv2.LINE_AA)
