"""Synthetic test images with known centrelines: pen strokes on paper and coloured rods on a table.

A stroke of width w along a curve covers each pixel by ``clip(w/2 + 0.5 - d, 0, 1)``, d the distance of
the pixel centre to the curve (an anti-aliased round-capped tube, exact to ~0.01 px, any real width).
Strokes are composited in order, so a later stroke lies over an earlier one. Used by the tests and the
benchmark; also handy to try the CLI (see ``example_curves``). Units: pixels, curves (n, 2) (row, col).
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import cKDTree

from rod_deploy.perception.centreline import resample


def stroke_coverage(shape, curve: np.ndarray, width_px: float) -> np.ndarray:
    """float32 (H, W) coverage in [0, 1] of a round-capped stroke of ``width_px`` along ``curve``."""
    dense = resample(np.asarray(curve, float), 0.2)
    cov = np.zeros(shape[:2], dtype=np.float32)
    band = np.zeros(shape[:2], dtype=np.uint8)
    thick = int(np.ceil(width_px)) + 4
    cv2.polylines(band, [np.round(dense[:, ::-1]).astype(np.int32)], False, 1, thick)
    for r, c in np.round(dense[[0, -1]]).astype(int):
        cv2.circle(band, (int(c), int(r)), thick // 2 + 1, 1, -1)
    flat = np.flatnonzero(band)
    rows, cols = np.divmod(flat, shape[1])
    d, _ = cKDTree(dense).query(np.stack([rows, cols], axis=1))
    cov.flat[flat] = np.clip(0.5 * width_px + 0.5 - d, 0.0, 1.0)
    return cov


def table_background(shape, background, gradient: float, texture: float, texture_sigma_px: float,
                     rng: np.random.Generator) -> np.ndarray:
    """Float32 BGR image of an empty table: the ``background`` colour, a linear illumination ``gradient``
    (fraction of brightness lost across the image) and smooth random blotches of std ``texture`` grey levels
    (Gaussian-blurred noise of ``texture_sigma_px``, drawn from ``rng`` only when ``texture`` is set)."""
    h, w = shape[:2]
    img = np.empty((h, w, 3), np.float32)
    img[:] = np.asarray(background, np.float32)
    if gradient:
        ramp = 1.0 - gradient * (np.arange(w, dtype=np.float32) / max(w - 1, 1))
        img *= ramp[None, :, None]
    if texture:
        blot = cv2.GaussianBlur(rng.normal(0, 1, (h, w)).astype(np.float32), (0, 0), texture_sigma_px)
        blot *= texture / max(float(blot.std()), 1e-6)
        img += blot[:, :, None]
    return img


def draw_strokes(shape, curves, widths, colours, background=(235, 235, 230), noise_std: float = 2.0,
                 gradient: float = 0.0, blur_sigma: float = 0.0, texture: float = 0.0,
                 seed: int = 0) -> np.ndarray:
    """BGR uint8 image: ``curves`` with ``widths`` [px] and BGR ``colours`` over a background that may
    have a linear illumination ``gradient`` (fraction of brightness across the image), a random
    ``texture`` (std of smooth blotches, grey levels), Gaussian ``noise_std`` and optical blur."""
    rng = np.random.default_rng(seed)
    img = table_background(shape, background, gradient, texture, 6.0, rng)
    for curve, width, colour in zip(curves, widths, colours):
        cov = stroke_coverage(shape, curve, width)[:, :, None]
        img = img * (1.0 - cov) + np.asarray(colour, np.float32) * cov
    if blur_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_sigma)
    if noise_std > 0:
        img += rng.normal(0, noise_std, img.shape).astype(np.float32)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def curve_from_function(fn, t0: float, t1: float, n: int = 2000) -> np.ndarray:
    t = np.linspace(t0, t1, n)
    return np.stack(fn(t), axis=1)


def example_curves(size: int = 600) -> dict:
    """Named test curves (row, col) [px] filling a ``size`` x ``size`` image: open, self-crossing,
    closed, with corners."""
    c = size / 2.0
    s = size / 600.0
    curves = {
        'sine': curve_from_function(lambda t: (c + 120 * s * np.sin(t), 80 * s + t * (440 * s) / (3 * np.pi)),
                                    0, 3 * np.pi),
        # alpha loop (col ~ t^3 - 3t, row ~ t^2): crosses itself once, at t = +-sqrt(3), at 60 degrees
        'alpha': curve_from_function(lambda t: (c - 150 * s + 60 * s * t ** 2, c + 60 * s * (t ** 3 - 3 * t)),
                                     -2.15, 2.15),
        'spiral': curve_from_function(lambda t: (c + (40 + 22 * t) * s * np.sin(t),
                                                 c + (40 + 22 * t) * s * np.cos(t)), 0, 3.4 * np.pi),
        'circle': curve_from_function(lambda t: (c + 190 * s * np.sin(t), c + 190 * s * np.cos(t)),
                                      0, 2 * np.pi),
        'letter_l': np.array([[100, 200], [480, 200], [480, 420]], float) * s,
    }
    # letter U: two straight legs joined by a half circle
    t = np.linspace(np.pi, 0, 200)
    arc = np.stack([380 * s + 120 * s * np.sin(t), c + 120 * s * np.cos(t)], axis=1)
    curves['letter_u'] = np.vstack([[[120 * s, c - 120 * s]], arc, [[120 * s, c + 120 * s]]])
    return curves


def random_rod_curve(rng, shape, length_px: float, min_radius_px: float, margin_px: float = 20.0,
                     tries: int = 200) -> np.ndarray:
    """A random open curve of ``length_px`` whose radius of curvature never drops below ``min_radius_px``
    (an elastic rod or a pen stroke drawn without cusps), inside the image with ``margin_px`` to spare.
    Curvature along the arc is a random smooth function (a few sinusoids), integrated into heading and
    position; curves that leave the image are redrawn."""
    h, w = shape[:2]
    n = int(length_px) + 1
    s = np.linspace(0.0, length_px, n)
    for _ in range(tries):
        kappa = np.zeros(n)
        for _ in range(4):
            wavelength = rng.uniform(0.15, 1.0) * length_px
            kappa += rng.normal() * np.sin(2 * np.pi * s / wavelength + rng.uniform(0, 2 * np.pi))
        kappa *= rng.uniform(0.3, 1.0) / (min_radius_px * max(np.abs(kappa).max(), 1e-9))
        theta = rng.uniform(0, 2 * np.pi) + np.concatenate([[0.0], np.cumsum(0.5 * (kappa[1:] + kappa[:-1]))
                                                             * (s[1] - s[0])])
        steps = np.stack([np.sin(theta), np.cos(theta)], axis=1) * (s[1] - s[0])
        pts = np.cumsum(steps, axis=0)
        pts -= 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        span = pts.max(axis=0) - pts.min(axis=0)
        room = np.array([h, w]) - 2 * margin_px - span
        if np.any(room < 0):
            continue
        offset = np.array([margin_px, margin_px]) + 0.5 * span + rng.uniform(0, 1, 2) * room
        return pts + offset
    raise ValueError(f'could not fit a curve of {length_px} px in an image of {shape[:2]}')
