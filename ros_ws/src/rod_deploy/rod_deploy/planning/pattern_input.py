"""A pattern to deploy along (CONTRACTS.md section 4): a points file (x y [z] per line, metres, table frame) or an
image of a drawn stroke / a photographed rod with its pixel-to-table mapping (through the perception pipeline)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

IMAGE_SUFFIXES = {'.png', '.jpg', '.jpeg', '.bmp', '.tif', '.tiff'}


class PatternError(ValueError):
    """A pattern the planner cannot use; the message names the problem and the point."""


#: a pattern file's z column must be within this of 0: the points lie on the table (table frame, z = 0 there)
Z_TOLERANCE_M = 0.005


def load_pattern(path, m_per_px=None, origin=None, homography=None, object_index=0) -> np.ndarray:
    """(n, 2) pattern points [m] in the table frame, validated with :func:`check_pattern` (a points file's errors
    name the line)."""
    path = Path(path)
    if not path.exists():
        raise PatternError(f'pattern {path} does not exist')
    if path.suffix.lower() in IMAGE_SUFFIXES:
        return check_pattern(_pattern_from_image(path, m_per_px, origin, homography, object_index), str(path))
    from rod_deploy.perception.path_io import PathFileError, read_pattern_file_lines
    try:
        pts, lines = read_pattern_file_lines(path)
    except PathFileError as e:
        raise PatternError(f'pattern {e}' if str(e).startswith(str(path)) else f'pattern {path}: {e}') from None
    except (OSError, UnicodeDecodeError) as e:
        raise PatternError(f'pattern {path}: {e}') from None
    off = np.flatnonzero(~(np.abs(pts[:, 2]) <= Z_TOLERANCE_M))        # NaN too
    if off.size:
        i = int(off[0])
        raise PatternError(f'{path}, line {lines[i]}: z = {pts[i, 2]:.6g} m, but the pattern lies on the table (z = 0 '
                           f'in the table frame, CONTRACTS.md section 4): give the points in the table frame '
                           f'(x y, or x y 0)')
    return check_pattern(pts[:, :2], str(path), line_numbers=lines)


def _pattern_from_image(path, m_per_px, origin, homography, object_index):
    import cv2
    from rod_deploy.perception.pipeline import PerceptionError, perceive
    from rod_deploy.perception.pixel_mapping import MappingError, ScaleOrigin, default_origin, load_homography
    if m_per_px is None and homography is None:
        raise PatternError(f'pattern image {path} needs --m-per-px or --homography (the planner works in metres)')
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None or img.size == 0:
        raise PatternError(f'cannot read image {path}')
    try:
        if homography is not None:
            mapping = load_homography(homography)
            mapping.check_image(img.shape)
        else:
            if not m_per_px > 0:
                raise PatternError(f'--m-per-px must be > 0, got {m_per_px}')
            mapping = ScaleOrigin(m_per_px, *(origin if origin is not None else default_origin(img.shape)))
        result = perceive(img)
    except (MappingError, PerceptionError) as e:
        raise PatternError(f'{path}: {e}') from None
    if not 0 <= object_index < len(result.objects):
        raise PatternError(f'{path}: object {object_index} requested, the image has objects '
                           f'0..{len(result.objects) - 1}')
    pts = result.objects[object_index].points
    return np.stack(mapping.to_table(pts[:, 0], pts[:, 1]), axis=1)


def check_pattern(xy, name='pattern', min_spacing_m=1e-6, line_numbers=None) -> np.ndarray:
    """At least 3 finite points, no repeated consecutive points (within ``min_spacing_m``). The errors name the point
    (counted from 0) and, with ``line_numbers`` (the file's line of each point), its line."""
    xy = np.asarray(xy, float)
    if xy.ndim != 2 or xy.shape[1] < 2:
        raise PatternError(f'{name}: expected (x, y) points')
    xy = xy[:, :2]
    if len(xy) < 3:
        raise PatternError(f'{name}: a pattern needs at least 3 points, got {len(xy)}')

    def where(i):
        return f'line {line_numbers[i]} (point {i})' if line_numbers is not None else f'point {i}'

    bad = np.flatnonzero(~np.all(np.isfinite(xy), axis=1))
    if bad.size:
        raise PatternError(f'{name}: {where(bad[0])} is not finite ({xy[bad[0]].tolist()})')
    gaps = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    bad = np.flatnonzero(gaps < min_spacing_m)
    if bad.size:
        i = int(bad[0])
        raise PatternError(f'{name}: {where(i + 1)} ({xy[i + 1, 0]:.6g}, {xy[i + 1, 1]:.6g}) repeats '
                           f'{where(i)}; remove repeated points')
    return xy


def distance_to_polyline(points_xy, polyline_xy) -> np.ndarray:
    """Distance [m] of each point to the polyline (straight segments between consecutive polyline points)."""
    p = np.asarray(points_xy, float)[:, None, :]
    a, b = np.asarray(polyline_xy, float)[:-1][None], np.asarray(polyline_xy, float)[1:][None]
    ab = b - a
    u = np.clip(np.sum((p - a) * ab, axis=2) / np.maximum(np.sum(ab * ab, axis=2), 1e-30), 0.0, 1.0)
    return np.linalg.norm(p - (a + u[..., None] * ab), axis=2).min(axis=1)


#: points further apart than SPARSE_SPACING_M whose smooth curve strays more than SPARSE_NOTE_M from the straight
#: segments between them are reported (dense points stray by the smoothing alone: 0.8-1.2 mm on the published ones)
SPARSE_NOTE_M, SPARSE_SPACING_M = 0.002, 0.01


def sparse_points_note(points_xy, curve_xy):
    """A note (str) when the points are so sparse (some further apart than SPARSE_SPACING_M) that the smooth curve
    through them (the planner's spline, nodes ``curve_xy``) strays more than SPARSE_NOTE_M from the straight segments
    between them, else None: the planner
    lays the curve, while Eq. 17 (``rod-deploy evaluate``) compares with the segments."""
    points_xy = np.asarray(points_xy, float)
    spacing = float(np.linalg.norm(np.diff(points_xy, axis=0), axis=1).max())
    if spacing <= SPARSE_SPACING_M:
        return None
    gap = float(distance_to_polyline(curve_xy, points_xy).max())
    if gap <= SPARSE_NOTE_M:
        return None
    return (f'the pattern\'s points are up to {100 * spacing:.1f} cm apart: the planner lays a smooth curve through '
            f'them, up to {1000 * gap:.1f} mm from the straight segments between them, while Eq. 17 compares with '
            f'those segments; give the points denser (every few mm) if the shape between them matters')
