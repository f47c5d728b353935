"""Files of perceived paths: ``path.csv`` (all objects) and the contract's pattern text file (one curve).

``path.csv``: header ``object,row,col,x,y``; object ids from 0, the points of each object in order from
one end (a closed object repeats its first point at the end); (row, col) in pixels (integer values at
pixel centres), (x, y) in table metres.

Pattern text file (CONTRACTS.md section 4): one point per line, ``x y z`` in metres in the table frame
(z = 0 on the table); readers also accept ``x y`` lines, blank lines and ``#`` comments.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

PATH_CSV_HEADER = ('object', 'row', 'col', 'x', 'y')


class PathFileError(ValueError):
    """A malformed path.csv or pattern file."""


def write_path_csv(path, objects_px: list, objects_xy: list):
    """Write ``path.csv``: ``objects_px`` and ``objects_xy`` are lists of (n_k, 2) arrays, (row, col) [px]
    and (x, y) [m], one per object, in object order."""
    if len(objects_px) != len(objects_xy):
        raise ValueError('one pixel path and one metric path per object')
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(PATH_CSV_HEADER)
        for k, (px, xy) in enumerate(zip(objects_px, objects_xy)):
            px, xy = np.asarray(px, float), np.asarray(xy, float)
            if px.shape != xy.shape:
                raise ValueError(f'object {k}: pixel and metric paths differ in shape')
            for (r, c), (x, y) in zip(px, xy):
                w.writerow((k, f'{r:.3f}', f'{c:.3f}', f'{x:.6f}', f'{y:.6f}'))


def read_path_csv(path) -> dict:
    """{object id: (points_px (n, 2) (row, col), points_xy (n, 2) (x, y))} from a ``path.csv``."""
    path = Path(path)
    with open(path, newline='') as f:
        rows = list(csv.reader(f))
    if not rows or tuple(h.strip() for h in rows[0]) != PATH_CSV_HEADER:
        raise PathFileError(f'{path}: header must be {",".join(PATH_CSV_HEADER)}')
    data: dict = {}
    for i, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        try:
            k, r, c, x, y = int(row[0]), *map(float, row[1:5])
        except (ValueError, IndexError):
            raise PathFileError(f'{path}, line {i}: expected object,row,col,x,y') from None
        data.setdefault(k, []).append((r, c, x, y))
    out = {}
    for k, pts in sorted(data.items()):
        a = np.array(pts)
        out[k] = (a[:, :2], a[:, 2:])
    return out


def write_pattern_file(path, points_xy: np.ndarray, z_m: float = 0.0):
    """Write the pattern text file: ``x y z`` per line [m]."""
    pts = np.asarray(points_xy, float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
        raise ValueError('a pattern needs at least two (x, y) points')
    with open(path, 'w') as f:
        for x, y in pts:
            f.write(f'{x:.6f} {y:.6f} {z_m:.6f}\n')


def read_pattern_file(path) -> np.ndarray:
    """(n, 3) points [m] of a pattern text file (z = 0 where a line gives only x y); see
    :func:`read_pattern_file_lines`."""
    return read_pattern_file_lines(path)[0]


#: names a header line may give its columns (skipped when it is the first line that is not a comment)
_HEADER_NAMES = {'x', 'y', 'z', 'x_m', 'y_m', 'z_m', 'x[m]', 'y[m]', 'z[m]'}


def read_pattern_file_lines(path):
    """((n, 3) points [m], (n,) line numbers from 1) of a pattern text file.

    One point per line, ``x y`` or ``x y z``, separated by spaces, tabs or commas (``0.1, 0.2``); ``#`` comments,
    blank lines, a UTF-8 byte-order mark and one header line naming the columns (``x,y`` or ``x y z``) before the
    first point are skipped. Refused with the line named, where the numbers would have to be guessed: a line that
    mixes commas and spaces between its numbers (``0,15 0``: decimal commas?), semicolons, words, or other than two
    or three values. An empty file gives a (0, 3) array."""
    path = Path(path)
    pts, line_numbers = [], []
    for i, raw in enumerate(path.read_text(encoding='utf-8-sig').splitlines(), start=1):
        line = raw.split('#', 1)[0].strip()
        if not line:
            continue
        shown = line if len(line) <= 60 else line[:57] + '...'
        if ';' in line:
            raise PathFileError(f'{path}, line {i}: "{shown}": semicolons are not separators here; write x y [z] '
                                f'in metres separated by spaces or commas, with "." as the decimal point')
        if ',' in line:
            fields = [f.strip() for f in line.split(',')]
            if fields[-1] == '':                       # one trailing comma
                fields = fields[:-1]
            if any(len(f.split()) > 1 for f in fields):
                raise PathFileError(f'{path}, line {i}: "{shown}" mixes commas and spaces between numbers '
                                    f'(decimal commas?); write x y [z] separated by spaces or by commas, with "." as '
                                    f'the decimal point')
        else:
            fields = line.split()
        if not pts and all(f.lower() in _HEADER_NAMES for f in fields):
            continue                                    # a header line naming the columns
        vals = []
        for f in fields:
            try:
                vals.append(float(f))
            except ValueError:
                raise PathFileError(f'{path}, line {i}: "{f}" is not a number (expected x y [z] in metres)') from None
        if len(vals) not in (2, 3):
            raise PathFileError(f'{path}, line {i}: expected "x y" or "x y z", got {len(vals)} values ("{shown}")')
        pts.append(vals + [0.0] * (3 - len(vals)))
        line_numbers.append(i)
    return np.array(pts, float).reshape(-1, 3), np.array(line_numbers, int)


def deployed_order(points_xy: np.ndarray, closed: bool, start_near=None) -> np.ndarray:
    """One perceived path as the contract's deployed shape (ordered from the first deployed end): as
    given, or from the end nearest to ``start_near`` (x, y); a closed path (first point repeated at the
    end) is rolled to start, and end, at its point nearest to ``start_near``."""
    pts = np.asarray(points_xy, float)
    if start_near is None:
        return pts
    q = np.asarray(start_near, float)
    if closed:
        body = pts[:-1] if len(pts) > 1 and np.allclose(pts[0], pts[-1]) else pts
        k = int(np.argmin(np.hypot(*(body - q).T)))
        body = np.roll(body, -k, axis=0)
        return np.vstack([body, body[:1]])
    if np.linalg.norm(pts[-1] - q) < np.linalg.norm(pts[0] - q):
        return pts[::-1].copy()
    return pts
