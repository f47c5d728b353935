"""Deployment error of the paper's Eq. 17 and the deployed-shape file (contract CSV ``x,y``).

Both curves are resampled by arc length to N = 50 points; e_mean is the mean distance between corresponding points
and sigma their standard deviation (the paper's Eq. 17 prints the square root of the mean deviation, which is the
standard deviation once squared; we report the standard deviation), in cm.

Which part of the rod is compared: the deployed curve from its first deployed end, cut at the pattern's length when
it is longer (the rod beyond is the part still lifting off towards the gripper); ``coverage`` = deployed length /
pattern length tells how much of the pattern was laid. A drawn stroke has no direction (CONTRACTS.md section 4):
the better of the two directions of the deployed curve is taken (``reversed`` says which).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

N_POINTS = 50


class DeployedShapeError(ValueError):
    """A deployed-shape file that does not follow the contract."""


def arc_length(xy):
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])


def resample(xy, n=N_POINTS, length=None):
    """n points equally spaced by arc length along ``xy`` (up to ``length`` if given)."""
    s = arc_length(xy)
    end = s[-1] if length is None else min(length, s[-1])
    u = np.linspace(0.0, end, n)
    return np.column_stack([np.interp(u, s, xy[:, k]) for k in range(xy.shape[1])])


def eq17_error(pattern_xy, deployed_xy, n=N_POINTS, directed=False) -> dict:
    """Eq. 17 between a prescribed pattern and a deployed curve (metres in, cm out)."""
    pattern_xy = np.asarray(pattern_xy, float)[:, :2]
    deployed_xy = np.asarray(deployed_xy, float)[:, :2]
    if len(pattern_xy) < 2 or len(deployed_xy) < 2:
        raise ValueError('Eq. 17 needs at least two points on each curve')
    lp = float(arc_length(pattern_xy)[-1])
    best = None
    for rev in ((False,) if directed else (False, True)):
        d = deployed_xy[::-1] if rev else deployed_xy
        ld = float(arc_length(d)[-1])
        a = resample(pattern_xy, n)
        b = resample(d, n, length=lp)
        dist = np.linalg.norm(a - b, axis=1)
        out = {'e_mean_cm': 100 * float(dist.mean()), 'sigma_cm': 100 * float(dist.std()),
               'e_max_cm': 100 * float(dist.max()), 'pattern_length_m': lp, 'deployed_length_m': ld,
               'coverage': ld / lp if lp > 0 else 0.0, 'reversed': rev, 'n_points': n}
        if best is None or out['e_mean_cm'] < best['e_mean_cm']:
            best = out
    return best


def write_deployed_csv(path, xy):
    xy = np.asarray(xy, float)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, xy[:, :2], delimiter=',', header='x,y', comments='', fmt='%.9g')


def read_deployed_csv(path) -> np.ndarray:
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as e:
        raise DeployedShapeError(f'cannot read deployed shape {path}: {e.strerror}') from None
    if not lines or lines[0].replace(' ', '') != 'x,y':
        raise DeployedShapeError(f'deployed shape {path}: the first line must be the header "x,y"')
    try:
        xy = np.loadtxt(path, delimiter=',', skiprows=1, ndmin=2)
    except ValueError as e:
        raise DeployedShapeError(f'deployed shape {path}: {e}') from None
    if xy.shape[1] != 2 or len(xy) < 2:
        raise DeployedShapeError(f'deployed shape {path}: need at least 2 rows "x,y", got shape {xy.shape}')
    if not np.all(np.isfinite(xy)):
        raise DeployedShapeError(f'deployed shape {path}: values are not finite')
    return xy
