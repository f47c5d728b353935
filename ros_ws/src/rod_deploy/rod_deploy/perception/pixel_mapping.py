"""Pixel to table mapping (CONTRACTS.md section 4).

Two forms, both mapping (row, col) image pixels (integer values at pixel centres) to table metres (x to the
right, y towards the top of the image, z up out of the table):

* scale and origin: x = (col - c0) s, y = (r0 - row) s, with s [m/px] and the origin pixel (r0, c0);
* homography: (x, y, 1) ~ H (col, row, 1), H a 3x3 matrix (text file of 3 rows).

:func:`default_origin` is this project's choice when only a scale is given: the centre of the image's
bottom-left pixel, so that the whole image has x >= 0 and y >= 0.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


class MappingError(ValueError):
    """An invalid scale, origin or homography."""


def default_origin(image_shape) -> tuple:
    """(row, col) of the bottom-left pixel centre."""
    return float(image_shape[0] - 1), 0.0


@dataclass(frozen=True)
class ScaleOrigin:
    m_per_px: float
    origin_row: float
    origin_col: float

    def __post_init__(self):
        if not (np.isfinite(self.m_per_px) and self.m_per_px > 0):
            raise MappingError(f'metres per pixel must be a positive number, got {self.m_per_px}')
        if not (np.isfinite(self.origin_row) and np.isfinite(self.origin_col)):
            raise MappingError(f'origin must be finite, got ({self.origin_row}, {self.origin_col})')

    def to_table(self, rows, cols):
        """(x, y) [m] of pixel coordinates."""
        rows, cols = np.asarray(rows, float), np.asarray(cols, float)
        return (cols - self.origin_col) * self.m_per_px, (self.origin_row - rows) * self.m_per_px

    def to_pixels(self, x, y):
        """(row, col) of table coordinates [m]."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        return self.origin_row - y / self.m_per_px, self.origin_col + x / self.m_per_px

    def describe(self) -> str:
        return (f'{self.m_per_px:g} m/px, origin pixel (row {self.origin_row:g}, col {self.origin_col:g}): '
                f'x = (col - c0) s, y = (r0 - row) s')


@dataclass(frozen=True)
class Homography:
    matrix: np.ndarray     # 3x3, (x, y, 1) ~ H (col, row, 1)

    def __post_init__(self):
        h = np.asarray(self.matrix, dtype=float)
        if h.shape != (3, 3):
            raise MappingError(f'a homography is a 3x3 matrix, got shape {h.shape}')
        if not np.all(np.isfinite(h)):
            raise MappingError('the homography has non-finite entries')
        if abs(np.linalg.det(h)) < 1e-12 * max(1.0, np.abs(h).max() ** 3):
            raise MappingError('the homography is singular')
        object.__setattr__(self, 'matrix', h)

    def to_table(self, rows, cols):
        rows, cols = np.asarray(rows, float), np.asarray(cols, float)
        v = self.matrix @ np.stack([cols.ravel(), rows.ravel(), np.ones(rows.size)])
        return (v[0] / v[2]).reshape(rows.shape), (v[1] / v[2]).reshape(rows.shape)

    def to_pixels(self, x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        v = np.linalg.solve(self.matrix, np.stack([x.ravel(), y.ravel(), np.ones(x.size)]))
        return (v[1] / v[2]).reshape(x.shape), (v[0] / v[2]).reshape(x.shape)

    def check_image(self, image_shape):
        """Raise :class:`MappingError` if the image (its corners) crosses the homography's horizon, where
        table coordinates go to infinity."""
        h, w = image_shape[:2]
        corners = np.array([[-0.5, -0.5, 1], [w - 0.5, -0.5, 1], [-0.5, h - 0.5, 1], [w - 0.5, h - 0.5, 1]]).T
        third = self.matrix[2] @ corners
        if np.any(np.abs(third) < 1e-12) or not (np.all(third > 0) or np.all(third < 0)):
            raise MappingError('the homography maps part of the image to infinity (its horizon crosses the '
                               'image); check the matrix and that it maps (col, row, 1) to (x, y, 1)')

    def describe(self) -> str:
        return 'homography (x, y, 1) ~ H (col, row, 1), H = ' + np.array2string(self.matrix, precision=6)


def load_homography(path) -> Homography:
    """Read a 3x3 homography from a text file of 3 rows of 3 numbers (spaces or commas; '#' comments)."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise MappingError(f'cannot read homography file {path}: {exc.strerror}') from None
    rows = []
    for line in text.splitlines():
        line = line.split('#', 1)[0].replace(',', ' ').strip()
        if line:
            try:
                rows.append([float(v) for v in line.split()])
            except ValueError:
                raise MappingError(f'homography file {path}: not a number in line "{line}"') from None
    if len(rows) != 3 or any(len(r) != 3 for r in rows):
        raise MappingError(f'homography file {path} must hold 3 rows of 3 numbers, got {[len(r) for r in rows]}')
    return Homography(np.array(rows))
