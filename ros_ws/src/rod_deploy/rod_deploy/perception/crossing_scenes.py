"""Synthetic photos of rods crossing each other and themselves, with exact centrelines and over/under.

What mBEST-style perception must get right is the order of a centreline through crossings; these scenes
stress exactly that: two rods crossing three times with one passing under a loop of the other, shallow
crossings, a rod crossing itself (a loop, a cursive letter 'e', an overhand knot), two rods crossing twice,
and random scenes of 1-3 rods with up to 4 crossings.

Rendering (:func:`render_rod_scene`): each rod is a tube of width w along its centreline, lit as a
cylinder (Lambert, one light from a random azimuth, plus ambient), on a table with an illumination
gradient and smooth texture. The true crossings of the centrelines are found (:func:`curve_crossings`);
at each, one strand is raised (by the other's width, ramped over a few widths of arc) and painted over
the lower one, and every piece of rod casts a blurred shadow, offset with its height, onto whatever lies
below it (the table, the lower rod at a crossing). Then optical blur and noise. Rods are painted in short
pieces (flat cut, each pixel taking the piece that owns its nearest centreline point) so that a rod can
pass over and under itself. Units: pixels, curves (n, 2) (row, col).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.spatial import cKDTree

from rod_deploy.perception.centreline import arc_length, resample
from rod_deploy.perception.synthetic import curve_from_function, random_rod_curve, table_background

# BGR rod colours; several are close to each other (a colour alone often cannot decide)
PALETTE = [(90, 90, 230), (60, 220, 200), (200, 200, 60), (50, 200, 50), (230, 120, 200), (40, 140, 250),
           (200, 200, 200), (60, 60, 200), (40, 170, 230)]
MIN_ANGLE_DEG = 25.0        # crossings of the other kinds are at least this steep ('shallow': 12-28 deg)
MIN_CONTRAST = 40.0         # grey levels between a rod's shaded side and the table (some channel)
SCENE_KINDS = ('under_loop', 'shallow', 'self_loop', 'letter_e', 'knot', 'cross_twice', 'random')


@dataclass
class TrueCrossing:
    """A crossing of the true centrelines: rod ``rods[k]`` at arc length ``s_px[k]``; ``over`` = 0 or 1, the
    index into ``rods`` of the strand on top."""
    rods: tuple
    s_px: tuple
    position: np.ndarray
    angle_rad: float        # between the two strands, in [0, pi/2]
    over: int = 0


@dataclass
class RodScene:
    image: np.ndarray                       # BGR uint8
    curves: list                            # true centrelines (row, col) [px]
    widths: list
    colours: list
    crossings: list = field(default_factory=list)   # TrueCrossing
    kind: str = ''


def curve_crossings(curves: list, step_px: float = 1.0, min_separation_px: float = 10.0) -> list:
    """All crossings of the polylines ``curves`` with each other and themselves (segments of one curve
    closer than ``min_separation_px`` of arc do not count)."""
    dense = [resample(np.asarray(c, float), step_px) for c in curves]
    out = []
    for i in range(len(dense)):
        for j in range(i, len(dense)):
            a, b = dense[i], dense[j]
            sa, sb = arc_length(a), arc_length(b)
            p, r = a[:-1], a[1:] - a[:-1]
            q, s = b[:-1], b[1:] - b[:-1]
            rxs = r[:, None, 0] * s[None, :, 1] - r[:, None, 1] * s[None, :, 0]
            qp = q[None, :, :] - p[:, None, :]
            with np.errstate(divide='ignore', invalid='ignore'):
                t = (qp[..., 0] * s[None, :, 1] - qp[..., 1] * s[None, :, 0]) / rxs
                u = (qp[..., 0] * r[:, None, 1] - qp[..., 1] * r[:, None, 0]) / rxs
            hit = (np.abs(rxs) > 1e-12) & (t >= 0) & (t < 1) & (u >= 0) & (u < 1)
            if i == j:
                hit &= sb[None, :-1] > sa[:-1, None] + min_separation_px
            for k, m in zip(*np.nonzero(hit)):
                pos = p[k] + t[k, m] * r[k]
                cosang = abs(np.dot(r[k], s[m])) / (np.linalg.norm(r[k]) * np.linalg.norm(s[m]))
                out.append(TrueCrossing((i, j), (sa[k] + t[k, m] * (sa[k + 1] - sa[k]),
                                                 sb[m] + u[k, m] * (sb[m + 1] - sb[m])), pos,
                                        float(np.arccos(np.clip(cosang, 0, 1)))))
    return out


def _heights(curves, widths, crossings, ramp_factor=2.5):
    """Height [px] of each rod's centreline above the table, per point of ``curves`` (resampled at 1 px)."""
    s_all = [arc_length(c) for c in curves]
    z = [np.zeros(len(c)) for c in curves]
    for c in crossings:
        k = c.over
        rod, other = c.rods[k], c.rods[1 - k]
        h = widths[other]
        ramp = ramp_factor * max(widths[rod], widths[other])
        x = np.clip(np.abs(s_all[rod] - c.s_px[k]) / ramp, 0, 1)
        z[rod] = np.maximum(z[rod], h * 0.5 * (1 + np.cos(np.pi * x)))
    return z


def render_rod_scene(shape, curves, widths, colours, crossings, background=(60, 55, 50), texture=10.0,
                     gradient=0.2, light_azimuth_rad=0.7, ambient=0.45, shadow_strength=0.5,
                     shadow_px_per_px=0.5, blur_sigma=0.8, noise_std=3.0, seed=0) -> np.ndarray:
    """BGR uint8 photo of rods along ``curves`` (see module docstring); ``crossings`` from
    :func:`curve_crossings` with ``over`` set."""
    rng = np.random.default_rng(seed)
    h, w = shape[:2]
    img = table_background(shape, background, gradient, texture, 4.0, rng)
    curves = [resample(np.asarray(c, float), 1.0) for c in curves]
    heights = _heights(curves, widths, crossings)
    light = np.array([np.sin(light_azimuth_rad), np.cos(light_azimuth_rad)])     # (row, col) in the plane
    shadow_dir = -light
    pieces = []
    for rod, (c, z) in enumerate(zip(curves, heights)):
        n = len(c)
        size = int(max(8, 2 * widths[rod]))
        for a in range(0, n - 1, size):
            b = min(a + size, n - 1)
            pieces.append((float(z[a:b + 1].mean()), rod, a, b))
    pieces.sort(key=lambda p: p[0])
    top = np.zeros((h, w), np.float32)          # height of the painted surface [px] (table: 0)
    for z_mean, rod, a, b in pieces:
        c, wr = curves[rod], widths[rod]
        m = int(np.ceil(wr)) + 2
        lo, hi = max(0, a - m), min(len(c), b + m + 1)
        dense = resample(c[lo:hi], 0.25)
        ext_s = arc_length(c[lo:hi])
        band = np.zeros((h, w), np.uint8)
        cv2.polylines(band, [np.round(c[lo:hi, ::-1]).astype(np.int32)], False, 1, int(np.ceil(wr)) + 4)
        flat = np.flatnonzero(band)
        if not flat.size:
            continue
        rows, cols = np.divmod(flat, w)
        pix = np.stack([rows, cols], axis=1).astype(float)
        d, k = cKDTree(dense).query(pix)
        s_near = k * (ext_s[-1] / max(len(dense) - 1, 1)) + (lo if lo else 0)
        own = (s_near >= a - 0.5 * (a == 0) * 1e9) & (s_near < b + (b == len(c) - 1) * 1e9)
        tang = np.gradient(dense, axis=0)[k]
        tang /= np.maximum(np.linalg.norm(tang, axis=1, keepdims=True), 1e-9)
        rel = pix - dense[k]
        lateral = tang[:, 0] * rel[:, 1] - tang[:, 1] * rel[:, 0]         # signed distance across the rod
        cov = np.clip(0.5 * wr + 0.5 - d, 0, 1) * own
        keep = cov > 0
        if not keep.any():
            continue
        rows, cols, cov, lateral, tang = rows[keep], cols[keep], cov[keep], lateral[keep], tang[keep]
        x = np.clip(lateral / (0.5 * wr), -1, 1)
        nperp = np.stack([tang[:, 1], -tang[:, 0]], axis=1)            # unit normal in the plane (row, col)
        lambert = x * (nperp @ light) * 0.8 + np.sqrt(1 - x ** 2) * 0.6     # light 37 deg above the horizon
        shade = ambient + (1 - ambient) * np.clip(lambert, 0, 1)
        # shadow onto everything already painted (lower), offset with the height of the piece's top
        if shadow_strength > 0:
            off = shadow_dir * shadow_px_per_px * (z_mean + 0.5 * wr)
            sr = np.clip(np.round(rows + off[0]).astype(int), 0, h - 1)
            sc = np.clip(np.round(cols + off[1]).astype(int), 0, w - 1)
            r0, r1, c0, c1 = sr.min(), sr.max() + 1, sc.min(), sc.max() + 1
            pad = int(np.ceil(0.5 * wr)) + 3
            r0, c0 = max(0, r0 - pad), max(0, c0 - pad)
            r1, c1 = min(h, r1 + pad), min(w, c1 + pad)
            sh = np.zeros((r1 - r0, c1 - c0), np.float32)
            sh[sr - r0, sc - c0] = cov
            sh = cv2.GaussianBlur(sh, (0, 0), 0.25 * wr + 0.5)
            sh *= top[r0:r1, c0:c1] < z_mean + 0.5 * wr          # only on what lies below this piece
            img[r0:r1, c0:c1] *= (1 - shadow_strength * np.clip(sh, 0, 1))[:, :, None]
        col = np.asarray(colours[rod], np.float32)[None, :] * shade[:, None]
        img[rows, cols] = img[rows, cols] * (1 - cov[:, None]) + col * cov[:, None]
        top[rows[cov >= 0.5], cols[cov >= 0.5]] = z_mean + wr
    if blur_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_sigma)
    if noise_std > 0:
        img += rng.normal(0, noise_std, img.shape).astype(np.float32)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


# ---- shapes -------------------------------------------------------------------------------------------

def _place(curve, rng, shape, margin=30.0):
    """Rotate ``curve`` randomly about its centre and put it at a random place inside ``shape``; None if
    it does not fit."""
    a = rng.uniform(0, 2 * np.pi)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    p = (curve - curve.mean(axis=0)) @ rot.T
    span = p.max(axis=0) - p.min(axis=0)
    room = np.array(shape[:2]) - 2 * margin - span
    if np.any(room < 0):
        return None
    return p - p.min(axis=0) + margin + rng.uniform(0, 1, 2) * room


def loop_curve(rng, radius_px, t_in=None, t_out=None):
    """A rod with one loop (the alpha curve row = b t^2, col = a (t^3 - 3 t), which crosses itself at
    t = -+sqrt(3)): ``radius_px`` is the radius of curvature at the loop's far end, 9 a^2 / (2 b); the
    crossing angle 2 atan(b / (sqrt(3) a)) is drawn between 40 and 110 degrees; the rod runs from
    ``-t_in`` to ``t_out`` (default: both 2.4-2.9, leads of a few loop sizes)."""
    ratio = np.tan(0.5 * np.radians(rng.uniform(40, 110))) * np.sqrt(3)          # b / a
    a = 2 * ratio * radius_px / 9
    b = ratio * a
    t0 = -(t_in if t_in is not None else rng.uniform(2.4, 2.9))
    t1 = t_out if t_out is not None else rng.uniform(2.4, 2.9)
    t = np.linspace(t0, t1, 4000)
    return resample(np.stack([b * t ** 2, a * (t ** 3 - 3 * t)], axis=1), 1.0)


def letter_e_curve(rng, width_px):
    """A cursive 'e': a short lead-in that the loop crosses a few widths after the rod's start, the loop,
    and a long exit (the way a deployed letter 'e' lies)."""
    radius = rng.uniform(3.5, 5.5) * width_px
    return loop_curve(rng, radius, t_in=rng.uniform(1.95, 2.1), t_out=rng.uniform(2.8, 3.3))


def knot_curve(size_px, gap=0.45):
    """An overhand knot as it lies on the table: an open trefoil with its two ends led out."""
    fn = (lambda t: (-(np.cos(t) - 2 * np.cos(2 * t)), np.sin(t) + 2 * np.sin(2 * t)))
    c = curve_from_function(fn, gap, 2 * np.pi - gap, 1500) * (size_px / 6.0)
    lead = 0.35 * size_px
    t0 = c[1] - c[0]
    t1 = c[-1] - c[-2]
    t0, t1 = t0 / np.linalg.norm(t0), t1 / np.linalg.norm(t1)
    head = c[0] - np.linspace(lead, 0, 60, endpoint=False)[:, None] * t0
    tail = c[-1] + np.linspace(0, lead, 60)[1:, None] * t1
    return np.vstack([head, c, tail])


def _far_from_ends(curves, crossings, widths, factor=3.0):
    """Every crossing at least ``factor`` widths of arc from either rod's ends (an end in a crossing is a
    different problem: a T, not an X)."""
    for c in crossings:
        for k in (0, 1):
            rod = c.rods[k]
            length = arc_length(resample(curves[rod], 1.0))[-1]
            if c.s_px[k] < factor * widths[rod] or c.s_px[k] > length - factor * widths[rod]:
                return False
    return True


def _separated(crossings, min_px):
    """Crossings at least ``min_px`` apart (closer ones merge into a tangle that no one can read)."""
    for i in range(len(crossings)):
        for j in range(i + 1, len(crossings)):
            if np.linalg.norm(crossings[i].position - crossings[j].position) < min_px:
                return False
    return True


def crossing_scene(kind: str, seed: int, shape=(480, 640), tries: int = 400) -> RodScene:
    """One scene of ``kind`` (one of SCENE_KINDS), reproducible from ``seed``."""
    if kind not in SCENE_KINDS:
        raise ValueError(f'unknown scene kind {kind!r}; one of {", ".join(SCENE_KINDS)}')
    rng = np.random.default_rng(seed)
    for _ in range(tries):
        n_rods = {'under_loop': 2, 'shallow': 2, 'cross_twice': 2, 'random': int(rng.integers(1, 4))}.get(kind, 1)
        widths = list(rng.uniform(6, 14, n_rods))
        curves = _shapes(kind, rng, shape, widths)
        if curves is None:
            continue
        crossings = curve_crossings(curves)
        want = {'shallow': 1, 'self_loop': 1, 'letter_e': 1, 'cross_twice': 2}.get(kind)
        if kind == 'knot' and len(crossings) != 3:
            continue
        if kind == 'random' and len(crossings) > 4:
            continue
        if want is not None and len(crossings) != want:
            continue
        if kind == 'under_loop' and (sum(c.rods == (0, 1) for c in crossings) not in (2, 3)
                                     or sum(c.rods == (0, 0) for c in crossings) != 1):
            continue
        if kind == 'shallow' and not np.radians(12) <= crossings[0].angle_rad <= np.radians(28):
            continue
        if kind != 'shallow' and any(c.angle_rad < np.radians(MIN_ANGLE_DEG) for c in crossings):
            continue
        if not _far_from_ends(curves, crossings, widths):
            continue
        if not _separated(crossings, 2.5 * max(widths) / max(np.sin(min([c.angle_rad for c in crossings],
                                                                         default=1.0)), 0.3)):
            continue
        for c in crossings:
            if kind == 'under_loop' and c.rods == (0, 1):
                c.over = 0                                  # the lower rod passes under the loop
            elif kind == 'knot':
                c.over = 0                                  # assigned below: alternating
            else:
                c.over = int(rng.integers(0, 2))
        if kind == 'knot':                                  # over, under, over ... along the rod
            events = sorted([(c.s_px[k], ci, k) for ci, c in enumerate(crossings) for k in (0, 1)])
            for n_ev, (_, ci, k) in enumerate(events):
                if n_ev % 2 == 0:
                    crossings[ci].over = k
        pick = rng.choice(len(PALETTE), n_rods, replace=False)
        colours = [PALETTE[i] for i in pick]
        if kind in ('under_loop', 'cross_twice') and rng.uniform() < 0.5:
            colours[1] = tuple(int(np.clip(v + rng.integers(-20, 21), 0, 255)) for v in colours[0])
        dark = rng.uniform() < 0.5
        background = (20, 20, 22) if dark else tuple(int(v) for v in rng.integers(90, 150, 3))
        ambient = rng.uniform(0.4, 0.6)
        # every rod stands out from the table even on its shaded side (segmentation is not tested here)
        if any(np.abs(ambient * np.asarray(c, float) - background).max() < MIN_CONTRAST for c in colours):
            continue
        img = render_rod_scene(shape, curves, widths, colours, crossings, background=background,
                               texture=rng.uniform(3, 12), gradient=rng.uniform(0, 0.3),
                               light_azimuth_rad=rng.uniform(0, 2 * np.pi), ambient=ambient,
                               shadow_strength=rng.uniform(0.3, 0.6), blur_sigma=rng.uniform(0.5, 1.2),
                               noise_std=rng.uniform(2, 5), seed=seed)
        return RodScene(img, curves, widths, colours, crossings, kind)
    raise ValueError(f'no {kind} scene found in {tries} tries (seed {seed})')


def _shapes(kind, rng, shape, widths):
    size = min(shape[:2])
    if kind in ('self_loop', 'under_loop'):
        r = rng.uniform(3.5, 6.0) * widths[0] if kind == 'self_loop' else rng.uniform(4.5, 7.0) * widths[0]
        a = _place(loop_curve(rng, r), rng, shape)
        if a is None or kind == 'self_loop':
            return None if a is None else [a]
        # the other rod: a gentle curve through the loop's middle (crossing it twice, and a lead once)
        own = curve_crossings([a])
        if len(own) != 1:
            return None
        s = arc_length(a)
        loop = a[(s > own[0].s_px[0]) & (s < own[0].s_px[1])]
        centre = loop.mean(axis=0) + rng.normal(0, 0.1 * r, 2)
        ang = rng.uniform(0, np.pi)
        d = np.array([np.sin(ang), np.cos(ang)])
        half = 0.5 * rng.uniform(0.7, 1.0) * max(shape)
        t = np.linspace(-half, half, int(2 * half))
        wiggle = rng.uniform(-1, 1) * 0.08 * half * np.sin(np.pi * t / half + rng.uniform(0, np.pi))
        b = centre + t[:, None] * d + wiggle[:, None] * np.array([-d[1], d[0]])
        margin = 15.0
        inside = np.all((b >= margin) & (b <= np.array(shape[:2]) - margin), axis=1)
        if inside.sum() < 0.5 * len(b) or not inside[len(b) // 2]:
            return None
        mid = len(b) // 2                                      # the inside stretch through the middle
        lo = mid - int(np.argmin(inside[mid::-1])) + 1 if not inside[:mid + 1].all() else 0
        hi = mid + int(np.argmin(inside[mid:])) if not inside[mid:].all() else len(b)
        return [a, b[lo:hi]]
    if kind == 'letter_e':
        c = _place(letter_e_curve(rng, widths[0]), rng, shape)
        return None if c is None else [c]
    if kind == 'knot':
        c = _place(knot_curve(rng.uniform(0.55, 0.8) * size), rng, shape)
        return None if c is None else [c]
    if kind == 'shallow':
        n = len(widths)
        return [random_rod_curve(rng, shape, rng.uniform(0.6, 1.0) * max(shape), 15 * widths[k]) for k in range(n)]
    if kind == 'cross_twice':
        return [random_rod_curve(rng, shape, rng.uniform(0.6, 1.1) * max(shape), 6 * widths[k]) for k in range(2)]
    return [random_rod_curve(rng, shape, rng.uniform(300, 800), 5 * wk) for wk in widths]
