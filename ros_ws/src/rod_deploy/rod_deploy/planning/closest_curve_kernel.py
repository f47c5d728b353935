"""J^T J and J^T r of the closest curve's fit rows (``curvature_rate.closest_rate_limited_curve``) by a recurrence,
compiled with numba (``scripts/compile_kernels.sh`` compiles it once, at set-up).

The curve's points are the trapezoids of (cos theta, sin theta) cumulated from its fixed first point, so the
derivative of point i by an unknown a is G_ia = sum_{j < i} ds_j / 2 (dtheta_ja q_j + dtheta_(j+1)a q_(j+1)),
q = (-sin theta, cos theta): a cumulative sum. An unknown that changes the heading only over a stretch (a knot of
the piecewise linear curvature: d theta / d c_a is zero before its support and a constant H_a after it, from the node
``settled[a]`` on) turns the rest of the curve rigidly: there G_ia = H_a g_i + D_a, g_i the derivative of point i by
a heading change of 1 rad everywhere and D_a a constant vector. A column is therefore three pieces - zero before
``first[a]``, a few explicit rows, then H_a g_i + D_a - and each entry of J^T J is the explicit rows the two columns
share plus suffix sums of |g_i|^2, g_i and 1 from where both have settled: O(m p + p^2 w) for m nodes, p unknowns
and supports of w nodes, instead of the dense product's O(m p^2) (BLAS threads under load: 15-30 ms per product on
the 200-node spiral, benchmarks/results/planning_speed.md).
"""
from __future__ import annotations

import numpy as np
from numba import njit


def column_support(dtheta):
    """(first, settled) (p,) int64 of dtheta (m, p): the first row of each column that is not zero, and the first
    row from which the column keeps its last value to the end (0 for a column that is constant throughout)."""
    m, p = dtheta.shape
    nonzero = dtheta != 0.0
    first = np.where(nonzero.any(axis=0), np.argmax(nonzero, axis=0), m)
    differs = dtheta != dtheta[-1][None, :]
    settled = np.where(differs.any(axis=0), m - np.argmax(differs[::-1], axis=0), 0)
    return first.astype(np.int64), settled.astype(np.int64)


@njit(cache=True)
def fit_normal_equations(theta, dtheta, first, settled, half_ds, r_xy):
    """(J^T J (p, p), J^T r (p,)) of the rows r_xy[i] (i >= 1; row 0 is the fixed first point) of a curve whose
    points are the trapezoids of (cos theta, sin theta) on steps 2 half_ds (m - 1,) (in the rows' length unit),
    theta (m,) [rad] depending on the p unknowns through dtheta = d theta / d x (m, p); ``first``, ``settled``:
    :func:`column_support` of dtheta."""
    m, p = dtheta.shape
    qx = -np.sin(theta)
    qy = np.cos(theta)
    # g_i: d(point i) / d(a heading change of 1 rad at every node)
    gx = np.zeros(m)
    gy = np.zeros(m)
    for i in range(1, m):
        gx[i] = gx[i - 1] + half_ds[i - 1] * (qx[i - 1] + qx[i])
        gy[i] = gy[i - 1] + half_ds[i - 1] * (qy[i - 1] + qy[i])
    # suffix sums over the rows i >= e (e >= 1) of |g_i|^2, g_i, g_i . r_i and r_i
    s2 = np.zeros(m + 1)
    sgx = np.zeros(m + 1)
    sgy = np.zeros(m + 1)
    sgr = np.zeros(m + 1)
    srx = np.zeros(m + 1)
    sry = np.zeros(m + 1)
    for i in range(m - 1, 0, -1):
        s2[i] = s2[i + 1] + gx[i] * gx[i] + gy[i] * gy[i]
        sgx[i] = sgx[i + 1] + gx[i]
        sgy[i] = sgy[i + 1] + gy[i]
        sgr[i] = sgr[i + 1] + gx[i] * r_xy[i, 0] + gy[i] * r_xy[i, 1]
        srx[i] = srx[i + 1] + r_xy[i, 0]
        sry[i] = sry[i + 1] + r_xy[i, 1]
    # each column: its explicit rows first[a] <= i < settled[a], then H_a g_i + D_a
    width = 1
    for a in range(p):
        width = max(width, settled[a] - first[a])
    loc = np.zeros((p, width, 2))
    H = np.empty(p)
    Dx = np.empty(p)
    Dy = np.empty(p)
    for a in range(p):
        H[a] = dtheta[m - 1, a]
        Gx = 0.0
        Gy = 0.0
        e = settled[a]
        for i in range(max(first[a], 1), e + 1):
            Gx += half_ds[i - 1] * (dtheta[i - 1, a] * qx[i - 1] + dtheta[i, a] * qx[i])
            Gy += half_ds[i - 1] * (dtheta[i - 1, a] * qy[i - 1] + dtheta[i, a] * qy[i])
            if i < e:
                loc[a, i - first[a], 0] = Gx
                loc[a, i - first[a], 1] = Gy
        Dx[a] = Gx - H[a] * gx[e]
        Dy[a] = Gy - H[a] * gy[e]
    A = np.empty((p, p))
    g = np.empty(p)
    for a in range(p):
        ea = max(settled[a], 1)
        acc = 0.0
        for i in range(max(first[a], 1), min(ea, m)):
            acc += loc[a, i - first[a], 0] * r_xy[i, 0] + loc[a, i - first[a], 1] * r_xy[i, 1]
        if ea < m:
            acc += H[a] * sgr[ea] + Dx[a] * srx[ea] + Dy[a] * sry[ea]
        g[a] = acc
        for b in range(a, p):
            e = max(ea, settled[b])
            acc = 0.0
            for i in range(max(first[a], first[b], 1), min(e, m)):
                if i >= settled[a]:
                    ax, ay = H[a] * gx[i] + Dx[a], H[a] * gy[i] + Dy[a]
                else:
                    ax, ay = loc[a, i - first[a], 0], loc[a, i - first[a], 1]
                if i >= settled[b]:
                    bx, by = H[b] * gx[i] + Dx[b], H[b] * gy[i] + Dy[b]
                else:
                    bx, by = loc[b, i - first[b], 0], loc[b, i - first[b], 1]
                acc += ax * bx + ay * by
            if e < m:
                acc += (H[a] * H[b] * s2[e] + (H[a] * Dx[b] + H[b] * Dx[a]) * sgx[e]
                        + (H[a] * Dy[b] + H[b] * Dy[a]) * sgy[e] + (m - e) * (Dx[a] * Dx[b] + Dy[a] * Dy[b]))
            A[a, b] = acc
            A[b, a] = acc
    return A, g


@njit(cache=True)
def cholesky_solve(H, b):
    """(x, ok): x solving H x = b for a symmetric positive definite H (p, p) by its Cholesky factor H = L L^T, in
    plain compiled loops; ok is False (x zero) where a pivot is not positive (H not positive definite). Single-
    threaded on purpose: LAPACK's potrf (numpy's ``cholesky``) hands a matrix of more than about a hundred unknowns
    (the closest curve of a 0.7 m pattern on rod #1, knots every L_gb / 4) to OpenBLAS's threads, which on the loaded
    2-core machine made the cursive m's ``rod-deploy plan`` take 19.6 s of CPU and 39.9 s of wall clock
    (benchmarks/results/acceptance_rehearsal_fresh_r9.md; 0.73 s of planning with this kernel)."""
    p = H.shape[0]
    L = np.zeros((p, p))
    for j in range(p):
        s = H[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return np.zeros(p), False
        d = np.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, p):
            s = H[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
    y = np.empty(p)
    for i in range(p):                       # L y = b
        s = b[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    x = np.empty(p)
    for i in range(p - 1, -1, -1):           # L^T x = y
        s = y[i]
        for k in range(i + 1, p):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return x, True
