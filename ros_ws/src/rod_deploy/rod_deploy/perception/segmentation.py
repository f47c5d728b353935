"""Segmentation of drawn strokes or rods from a photo: a binary mask and a foreground-evidence image.

Method ``contrast`` (the default, chosen automatically: nothing to tune per image)
 1. Background B: the per-channel median of the image in 1/8-scale blocks, median filtered and scaled
    back up. It follows paper shading, a coloured or textured table and uneven light; strokes and rods
    are thin, so they do not move the median. (A background uniform to 10 grey levels is one colour.)
 2. Foreground evidence s = max over the colour channels of |I - B| (grey levels): dark ink on paper,
    coloured rods on a dark table and light rods on a dark table all score high, whatever the colour.
 3. Otsu's threshold T on s separates the objects from the background; if the two classes differ by less
    than ``min_contrast`` grey levels there is no object in the image.
 4. Pixels above T are object; so are pixels down to ``edge_fraction`` (0.3) of the local peak evidence
    (the max of s within one stroke width, w ~ 2 area / perimeter of the T mask, if that peak is at least
    0.6 T), which keeps the dim flanks of a shaded rod and dim rods next to bright ones; pixels below
    0.25 T never count (noise).
    The mask only has to get the topology right: widths and centres are measured later, sub-pixel, at
    the steepest edges of the evidence (:mod:`.centreline`).
 5. A 3x3 opening removes specks; holes smaller than a stroke's square are filled (glare); components
    smaller than ``min_area_px`` (default: three stroke-width squares) are dropped.
Methods ``dark`` and ``bright`` use one polarity only (s = B - I or I - B, e.g. for strokes on paper with
bright reflections or rods that cast shadows); ``threshold`` replaces Otsu's T by a fixed value.

Input: a BGR (OpenCV order) or grey uint8 image. Output: :class:`Segmentation`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numba import njit

from rod_deploy.perception.crossing_order import _pairwise_sum

METHODS = ('contrast', 'dark', 'bright')


class SegmentationError(ValueError):
    """The image holds no stroke or rod that can be segmented (empty, uniform, too faint)."""


@dataclass(frozen=True)
class SegmentationConfig:
    method: str = 'contrast'          # 'contrast' (|I - B|), 'dark' (B - I) or 'bright' (I - B)
    threshold: float | None = None    # evidence threshold [grey levels]; None: Otsu
    edge_fraction: float = 0.3        # mask down to this fraction of the local peak evidence
    min_contrast: float = 20.0        # [grey levels] between object and background class means
    min_area_px: int | None = None    # smallest object area kept; None: 3 stroke-width squares
    background_block_px: int = 8      # background sampling block [px]

    def __post_init__(self):
        if self.method not in METHODS:
            raise ValueError(f"segmentation method must be one of {METHODS}, got '{self.method}'")
        if not 0.0 < self.edge_fraction < 1.0:
            raise ValueError(f'edge_fraction must be in (0, 1), got {self.edge_fraction}')
        if self.threshold is not None and not 0 < self.threshold < 255:
            raise ValueError(f'threshold must be in (0, 255) grey levels, got {self.threshold}')


@dataclass
class Segmentation:
    mask: np.ndarray                     # bool (H, W): object pixels
    evidence: np.ndarray                 # uint8 (H, W): foreground evidence s
    peak: np.ndarray                     # uint8 (H, W): local peak evidence (max filter of s)
    threshold: float                     # global threshold T [grey levels]
    stroke_width_px: float               # rough stroke / rod width from area and perimeter
    method: str
    params: dict = field(default_factory=dict)
    background: np.ndarray | tuple = ()  # the background B: BGR image (H, W, 3) uint8, or one BGR colour

    def describe(self) -> str:
        p = ', '.join(f'{k}={v:.3g}' if isinstance(v, float) else f'{k}={v}' for k, v in self.params.items())
        return f'{self.method}: {p}'


def as_bgr(image: np.ndarray) -> np.ndarray:
    """uint8 BGR view of a grey, BGR or BGRA image."""
    img = np.asarray(image)
    if img.size == 0 or img.ndim not in (2, 3):
        raise SegmentationError(f'image is empty or not 2-D (shape {img.shape})')
    if img.dtype != np.uint8:
        if np.issubdtype(img.dtype, np.integer) and img.max(initial=0) > 255:
            img = (img / 257.0).round()
        img = np.clip(img, 0, 255).astype(np.uint8)
    if img.ndim == 2:
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    if img.shape[2] == 1:
        return cv2.cvtColor(img[:, :, 0], cv2.COLOR_GRAY2BGR)
    if img.shape[2] == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    if img.shape[2] != 3:
        raise SegmentationError(f'image has {img.shape[2]} channels; expected 1, 3 or 4')
    return img


def estimate_background(bgr: np.ndarray, block_px: int = 8, uniform_tolerance: float = 10.0):
    """Smooth background colour (see module docstring, step 1): a full-size BGR image, or a BGR tuple
    when the background is uniform (every block median within ``uniform_tolerance`` grey levels of the
    overall median, e.g. a black cloth), which saves the upsampling."""
    h, w = bgr.shape[:2]
    sh, sw = max(1, h // block_px), max(1, w // block_px)
    small = cv2.resize(bgr, (sw, sh), interpolation=cv2.INTER_LINEAR)   # samples; the median smooths
    k = min(15, (min(sh, sw) // 2) * 2 + 1)
    if k >= 3:
        small = median_blur(small, k)
    median = np.empty(3)
    spread = _channel_medians(np.ascontiguousarray(small).reshape(-1, 3), median)
    if k < 3 or spread <= uniform_tolerance:
        return tuple(float(v) for v in median)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def median_blur(image: np.ndarray, k: int) -> np.ndarray:
    """``cv2.medianBlur(image, k)`` of an (h, w, c) uint8 image, k odd and at most 181: per channel the median of the
    k x k window, the border replicated; the same numbers (a median of integers), computed by
    :func:`_median_plane`, about twice as fast as OpenCV's on the small background image here."""
    if image.dtype != np.uint8 or image.ndim != 3 or k % 2 != 1 or not 1 <= k <= 181:
        raise ValueError(f'median_blur needs an (h, w, c) uint8 image and an odd k <= 181, got {image.dtype} '
                         f'{image.shape}, k={k}')
    r = k // 2
    out = np.empty(image.shape, np.uint8)
    for ch in range(image.shape[2]):
        padded = cv2.copyMakeBorder(np.ascontiguousarray(image[:, :, ch]), r, r, r, r, cv2.BORDER_REPLICATE)
        _median_plane(padded, k, out, ch)
    return out


@njit(cache=True, nogil=True)
def _median_plane(padded, k, out, ch):
    """out[:, :, ch] = the median of every k x k window of the uint8 plane ``padded`` (the image with k // 2
    replicated pixels on each side), by running histograms (Perreault and Hebert 2007, "Median filtering in
    constant time"): one 256-level histogram per column over the window's rows, moved down a row at a time,
    and the window's histogram moved along a row by adding the entering column's and subtracting the leaving
    one's (int16 counts: k * k <= 32767); the median tracked from the previous one by the count of values
    below it. The median of k * k values is the value of rank k * k // 2."""
    hp, wp = padded.shape
    h, w = hp - k + 1, wp - k + 1
    half = (k * k) // 2
    columns = np.zeros((wp, 256), np.int16)
    for b in range(wp):
        for a in range(k):
            columns[b, padded[a, b]] += 1
    window = np.empty(256, np.int16)
    for i in range(h):
        if i > 0:
            for b in range(wp):
                columns[b, padded[i - 1, b]] -= 1
                columns[b, padded[i + k - 1, b]] += 1
        window[:] = 0
        for b in range(k):
            for v in range(256):
                window[v] += columns[b, v]
        m, below = 0, 0                          # the median and the count of values below it
        while below + window[m] <= half:
            below += window[m]
            m += 1
        out[i, 0, ch] = m
        for j in range(1, w):
            leaving, entering = columns[j - 1], columns[j + k - 1]
            change = 0
            for v in range(m):
                change += entering[v] - leaving[v]
            for v in range(256):
                window[v] += entering[v] - leaving[v]
            below += change
            while below > half:
                m -= 1
                below -= window[m]
            while below + window[m] <= half:
                below += window[m]
                m += 1
            out[i, j, ch] = m


@njit(cache=True, nogil=True)
def _channel_medians(pixels, median):
    """median[c] = ``np.median(pixels, axis=0)[c]`` of (n, 3) uint8 pixels (the middle value, or the mean of
    the two middle ones, from per-channel level counts); returns ``np.abs(pixels - median).max()``."""
    n = pixels.shape[0]
    counts = np.zeros((3, 256), np.int64)
    for i in range(n):
        for c in range(3):
            counts[c, pixels[i, c]] += 1
    spread = 0.0
    for c in range(3):
        lo, hi = 255, 0
        lower, upper = -1, -1                  # the values of rank (n - 1) // 2 and n // 2
        seen = 0
        for v in range(256):
            if counts[c, v] == 0:
                continue
            lo, hi = min(lo, v), max(hi, v)
            seen += counts[c, v]
            if lower < 0 and seen > (n - 1) // 2:
                lower = v
            if upper < 0 and seen > n // 2:
                upper = v
        median[c] = (np.float64(lower) + np.float64(upper)) / 2.0
        spread = max(spread, abs(lo - median[c]), abs(hi - median[c]))
    return spread


def foreground_evidence(bgr: np.ndarray, background, method: str) -> np.ndarray:
    """Evidence s (uint8): the largest channel difference between ``bgr`` and the ``background`` (an image
    or one BGR colour): |I - B| ('contrast'), B - I ('dark') or I - B ('bright'), clipped at 0."""
    bgr = np.ascontiguousarray(bgr)
    s = np.empty(bgr.shape[:2], np.uint8)
    polarity = METHODS.index(method)
    if isinstance(background, np.ndarray):
        _channel_max_difference(bgr, np.ascontiguousarray(background, dtype=np.uint8), polarity, s)
        return s
    # one colour (rounded to integers): the same differences from it, in integer arithmetic on the flat pixels
    colour = [int(round(v)) for v in background]
    _channel_max_from_colour(bgr.reshape(-1), colour[0], colour[1], colour[2], polarity, s.reshape(-1))
    return s


@njit(cache=True, nogil=True)
def _channel_max_difference(bgr, background, polarity, out):
    """out = max over the channels of |I - B| (polarity 0), B - I (1) or I - B (2), clipped at 0, in one
    pass (no full-size difference image)."""
    n = out.size
    pixels = bgr.reshape(n, 3)
    back = background.reshape(n, 3)
    evidence = out.reshape(n)
    sign = -1 if polarity == 1 else 1
    for i in range(n):
        best = 0
        for k in range(3):
            d = sign * (np.int32(pixels[i, k]) - np.int32(back[i, k]))
            if polarity == 0 and d < 0:
                d = -d
            best = max(best, d)
        evidence[i] = best


@njit(cache=True, nogil=True)
def _channel_max_from_colour(pixels, c_b, c_g, c_r, polarity, out):
    """out[i] = max over the channels of |I - c| (polarity 0), c - I (1) or I - c (2), clipped at 0, for the
    flat BGR ``pixels`` and one background colour c: integer arithmetic only (no table look-ups)."""
    for i in range(out.size):
        best = 0
        for k in range(3):
            c = c_b if k == 0 else (c_g if k == 1 else c_r)
            d = np.int32(pixels[3 * i + k]) - np.int32(c)
            if polarity == 0:
                d = abs(d)
            elif polarity == 1:
                d = -d
            best = max(best, d)
        out[i] = best


def segment(image: np.ndarray, config: SegmentationConfig = SegmentationConfig()) -> Segmentation:
    """Segment strokes or rods (see module docstring). Raises :class:`SegmentationError` if none."""
    bgr = as_bgr(image)
    background = estimate_background(bgr, config.background_block_px)
    s = foreground_evidence(bgr, background, config.method)
    # histogram statistics from every other row and column (4x fewer pixels), unless that leaves few
    # object pixels (thin strokes)
    sub = s[::2, ::2] if min(s.shape) >= 64 else s
    t_otsu, n_fg, mean_fg, mean_bg = _histogram_split(sub, config.threshold)
    if sub is not s and n_fg < 500:
        sub = s
        t_otsu, n_fg, mean_fg, mean_bg = _histogram_split(sub, config.threshold)
    if n_fg == 0 or n_fg == sub.size:
        raise SegmentationError('no stroke or rod found (the image is uniform)')
    if mean_fg - mean_bg < config.min_contrast:
        raise SegmentationError(
            f'no stroke or rod found: object/background contrast {mean_fg - mean_bg:.1f} grey levels '
            f'< {config.min_contrast:g}')
    # rough stroke width from area and perimeter (one erosion): w ~ 2 A / P
    _, coarse = cv2.threshold(s, t_otsu, 255, cv2.THRESH_BINARY)
    n_fg = int(np.count_nonzero(coarse))
    perimeter = max(1, n_fg - int(np.count_nonzero(cv2.erode(coarse, np.ones((3, 3), np.uint8)))))
    width = float(np.clip(2.0 * n_fg / perimeter, 1.0, 0.25 * min(s.shape)))
    k = int(2 * round(width) + 1) | 1
    peak = cv2.dilate(s, np.ones((k, k), np.uint8))
    # object: s > T, or s at least the local level (edge_fraction of the local peak, at least T / 4) where
    # that peak is at least 0.6 T; s and the thresholds are integers, so this is one comparison of s with
    # a 256-entry table of the peak: min(level(peak) if peak >= 0.6 T else never, floor(T) + 1)
    levels = cv2.max(cv2.multiply(np.arange(256, dtype=np.uint8), config.edge_fraction, dtype=cv2.CV_8U),
                     int(np.ceil(0.25 * t_otsu))).ravel().astype(np.int64)
    levels[np.arange(256) < np.ceil(0.6 * t_otsu)] = 256
    levels = np.minimum(levels, int(np.floor(t_otsu)) + 1)
    if levels.max() > 255:
        raise SegmentationError(f'threshold {t_otsu:g} leaves no object pixel')
    mask = cv2.compare(s, cv2.LUT(peak, levels.astype(np.uint8)), cv2.CMP_GE)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    min_area = config.min_area_px if config.min_area_px is not None else int(3 * width * width)
    mask = _clean_components(mask, hole_area=int(width * width), min_area=min_area)
    if not mask.any():
        raise SegmentationError(f'no stroke or rod found: every candidate is smaller than {min_area} px')
    params = {'background_block_px': config.background_block_px, 'otsu_threshold': float(t_otsu),
              'edge_fraction': config.edge_fraction, 'stroke_width_px': width, 'min_area_px': min_area,
              'contrast': mean_fg - mean_bg}
    return Segmentation(mask, s, peak, float(t_otsu), width, config.method, params, background)


def _histogram_split(s: np.ndarray, threshold):
    """(threshold T, pixels above T, their mean, mean of the rest) of an evidence image; T by Otsu
    unless given."""
    hist = np.zeros(256, np.float64)
    _count_levels(s, hist)
    t = _otsu(hist) if threshold is None else float(threshold)
    n_fg, sum_fg, sum_bg = _split_sums(hist, t)
    n_fg = int(n_fg)
    return t, n_fg, sum_fg / max(n_fg, 1), sum_bg / max(s.size - n_fg, 1)


@njit(cache=True, nogil=True)
def _split_sums(hist, t):
    """(pixels above level t, the sum of their levels, the sum of the others' levels) of a histogram of counts
    (integers: the sums are exact in any order)."""
    n_fg, sum_fg, sum_bg = 0.0, 0.0, 0.0
    for v in range(256):
        if v > t:
            n_fg += hist[v]
            sum_fg += hist[v] * v
        else:
            sum_bg += hist[v] * v
    return n_fg, sum_fg, sum_bg


@njit(cache=True, nogil=True)
def _count_levels(s, hist):
    """hist[v] += the number of pixels of the uint8 image (or strided view) ``s`` at level v (four interleaved
    integer counts: most pixels share one level, and one counter would make every update wait for the last)."""
    counts = np.zeros((4, 256), np.int64)
    for i in range(s.shape[0]):
        row = s[i]
        n = row.size
        j = 0
        while j + 4 <= n:
            counts[0, row[j]] += 1
            counts[1, row[j + 1]] += 1
            counts[2, row[j + 2]] += 1
            counts[3, row[j + 3]] += 1
            j += 4
        while j < n:
            counts[0, row[j]] += 1
            j += 1
    for v in range(256):
        hist[v] += counts[0, v] + counts[1, v] + counts[2, v] + counts[3, v]


def _otsu(hist: np.ndarray) -> float:
    """Otsu's threshold (grey level; values above it are foreground) of a 256-bin histogram."""
    hist = np.ascontiguousarray(hist, dtype=np.float64)
    if hist.shape != (256,):
        raise ValueError(f'expected a 256-bin histogram, got shape {hist.shape}')
    return float(_otsu_level(hist))


@njit(cache=True, nogil=True)
def _otsu_level(hist):
    """The level maximising the between-class variance (mu_T omega - mu)^2 / (omega (1 - omega)), omega and
    mu the cumulative sums of p = hist / max(sum, 1) and of p times the level; -1 where that is not finite;
    the first of equal maxima. The numpy formula's arithmetic: numpy's pairwise sum, running cumulative sums."""
    p = hist / max(_pairwise_sum(hist, 0, 256), 1.0)
    omega = np.empty(256)
    mu = np.empty(256)
    omega[0], mu[0] = p[0], p[0] * 0.0
    for v in range(1, 256):
        omega[v] = omega[v - 1] + p[v]
        mu[v] = mu[v - 1] + p[v] * v
    best, level = -np.inf, 0
    for v in range(256):
        denom = omega[v] * (1.0 - omega[v])
        x = mu[255] * omega[v] - mu[v]
        between = x * x / denom if denom != 0.0 else -1.0
        if not np.isfinite(between):
            between = -1.0
        if between > best:
            best, level = between, v
    return level


def _pixel_area(contour) -> float:
    """Pixel count enclosed by a boundary contour (polygon area plus half its perimeter)."""
    return cv2.contourArea(contour) + 0.5 * cv2.arcLength(contour, True) + 1.0


def _clean_components(mask_u8: np.ndarray, hole_area: int, min_area: int) -> np.ndarray:
    """Fill holes smaller than ``hole_area`` and drop components smaller than ``min_area`` (contours are
    much cheaper than labelling with statistics here)."""
    contours, hierarchy = cv2.findContours(mask_u8, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return mask_u8 > 0
    hierarchy = hierarchy[0]
    fill = [c for c, h in zip(contours, hierarchy) if h[3] >= 0 and cv2.contourArea(c) < hole_area]
    drop = [c for c, h in zip(contours, hierarchy) if h[3] < 0 and _pixel_area(c) < min_area]
    if fill:
        cv2.drawContours(mask_u8, fill, -1, 1, thickness=cv2.FILLED)
    if drop:
        cv2.drawContours(mask_u8, drop, -1, 0, thickness=cv2.FILLED)
    return mask_u8 > 0
