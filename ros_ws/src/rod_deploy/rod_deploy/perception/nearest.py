"""Distance from each of a set of points to the nearest point of another set, up to a bound, compiled.

:func:`nearest_distances` gives the distances that ``scipy.spatial.cKDTree(data).query(queries,
distance_upper_bound=bound)`` gives, bit for bit: the square root of the smallest (dr^2 + dc^2) over the
data points, infinity where that is not below bound^2 (scipy's bound is strict). Instead of a tree, the data
points are sorted into square cells larger than the bound (a counting sort), and each query looks at the
3 x 3 cells around its own: a data point closer than the bound lies in one of them. On the few hundred to
few thousand points of a traced path this is several times faster than building and querying a KD-tree
(whose construction dominates at these sizes). Units: pixels, points (row, col).
"""
from __future__ import annotations

import numpy as np
from numba import njit


def nearest_distances(data: np.ndarray, queries: np.ndarray, bound: float) -> np.ndarray:
    """(m,) distances from the (m, 2) ``queries`` to the nearest of the (n, 2) ``data`` points; ``inf`` where
    none is closer than ``bound`` (as ``cKDTree(data).query(queries, distance_upper_bound=bound)[0]``)."""
    data = np.ascontiguousarray(data, dtype=np.float64)
    queries = np.ascontiguousarray(queries, dtype=np.float64)
    if data.ndim != 2 or data.shape[1] != 2 or queries.ndim != 2 or queries.shape[1] != 2:
        raise ValueError(f'expected (n, 2) points, got shapes {data.shape} and {queries.shape}')
    if np.isnan(bound):
        raise ValueError('bound must not be nan')
    out = np.full(len(queries), np.inf)
    if len(data) and len(queries) and bound > 0:
        _nearest_within(data, queries, float(bound), out)
    return out


@njit(cache=True, nogil=True)
def _nearest_within(data, queries, bound, out):
    """out[q] = sqrt(min over data of dr * dr + dc * dc) where that minimum is below bound * bound (cells of
    side > bound, at most 2048 along each axis: larger cells for a large bound)."""
    n = data.shape[0]
    r_min, r_max = data[0, 0], data[0, 0]
    c_min, c_max = data[0, 1], data[0, 1]
    for i in range(1, n):
        r_min, r_max = min(r_min, data[i, 0]), max(r_max, data[i, 0])
        c_min, c_max = min(c_min, data[i, 1]), max(c_max, data[i, 1])
    cell = max(bound + 1.0, (r_max - r_min) / 2048.0, (c_max - c_min) / 2048.0)
    n_r = int((r_max - r_min) / cell) + 1
    n_c = int((c_max - c_min) / cell) + 1
    key = np.empty(n, np.int64)
    start = np.zeros(n_r * n_c + 1, np.int64)
    for i in range(n):
        key[i] = int((data[i, 0] - r_min) / cell) * n_c + int((data[i, 1] - c_min) / cell)
        start[key[i] + 1] += 1
    for k in range(n_r * n_c):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        order[fill[key[i]]] = i
        fill[key[i]] += 1
    bound2 = bound * bound
    for q in range(queries.shape[0]):
        qr, qc = queries[q, 0], queries[q, 1]
        gr = np.floor((qr - r_min) / cell)
        gc = np.floor((qc - c_min) / cell)
        if gr < -1.0 or gc < -1.0 or gr > n_r or gc > n_c:       # (also nan) farther than a cell from all data
            continue
        best = np.inf
        for a in range(max(int(gr) - 1, 0), min(int(gr) + 1, n_r - 1) + 1):
            for b in range(max(int(gc) - 1, 0), min(int(gc) + 1, n_c - 1) + 1):
                k = a * n_c + b
                for j in range(start[k], start[k + 1]):
                    p = order[j]
                    dr = qr - data[p, 0]
                    dc = qc - data[p, 1]
                    d2 = dr * dr + dc * dc
                    if d2 < best:
                        best = d2
        if best < bound2:
            out[q] = np.sqrt(best)
