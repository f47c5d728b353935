"""Zhang-Suen thinning (Zhang and Suen 1984) with Lü and Wang's correction (Lü and Wang 1986), followed by
Holt et al.'s staircase removal (Holt, Stewart, Clint and Perrott 1987), compiled; both rule tables are
derived here from the papers' conditions.

Neighbours of a pixel P are named as in Zhang and Suen: P2 = N, P3 = NE, P4 = E, P5 = SE, P6 = S, P7 = SW,
P8 = W, P9 = NW. B(P) is the number of object neighbours, A(P) the number of 0 -> 1 transitions in the
cyclic sequence P2, P3, ..., P9, P2.

1. Zhang-Suen: two parallel sub-iterations, repeated until a full iteration deletes nothing. Each deletes
   (all decisions taken on the image as it was before the sub-iteration) every object pixel with
   B(P) <= 6 and A(P) = 1, and, in the first, P2 P4 P6 = 0 and P4 P6 P8 = 0 (south-east boundary or
   north-west corner), in the second, P2 P4 P8 = 0 and P2 P6 P8 = 0 (north-west boundary or south-east corner).
   The paper's lower bound is 2 <= B(P); with it a diagonal stroke 2 pixels thick (a 4-connected
   staircase) is deleted whole, since every pixel of it has B = 2 or 3 and A = 1. Lü and Wang ("A comment on
   'A fast parallel algorithm for thinning digital patterns'", Commun. ACM 29(3), 1986) raise the bound to
   3 <= B(P) so that such strokes survive; that bound is used here.
2. The survivors of such strokes are staircases: a corner pixel with two object 4-neighbours at a right
   angle is not deleted (A(P) = 2 there), and its three 8-neighbours would read as a junction downstream
   (:mod:`.skeleton_graph`). Holt et al.'s staircase removal ("An improved parallel thinning algorithm",
   Commun. ACM 30(2), 1987; also in Parker, "Algorithms for Image Processing and Computer Vision", ch. 6)
   deletes such corners in two parallel passes: first every object pixel with N set and either (E set, NE
   clear, SW clear, and W or S clear) or (W set, NW clear, SE clear, and E or S clear); then the same with
   S in place of N (SE, SW in place of NE, NW and NW, NE in place of SW, SE).

A 2 x 2 square (or a blob that thins to one) still vanishes (every pixel has B = 3, A = 1): a 4-pixel speck,
which the pipeline drops anyway (:func:`.skeleton_graph.remove_small_parts`).

The tables of both rules (256 entries indexed by the neighbours' bits NW 1, N 2, NE 4, E 8, SE 16, S 32,
SW 64, W 128) are computed below from these conditions. This is not scikit-image's ``skeletonize``
(which the pipeline used before): its table differs from Zhang and Suen's conditions in 25 neighbourhoods
without a stated rule (nor symmetric under the half turn that maps the two sub-iterations onto each
other), and no published rule found reproduces it. The skeletons agree in topology on strokes and lie on
the same strokes within a few pixels (mostly at the ends); ``test_perception_thinning.py`` checks this,
``benchmarks/perception_thinning.py`` counts the differing pixels and ``benchmarks/results/HISTORY.md``
(perception) gives the effect on accuracy.

What is faster: an object pixel with no background neighbour is never deleted, so each pass visits only
a list of the pixels on the object's boundary (found once by a 3 x 3 erosion, then kept up to date from the
neighbours of the deleted pixels) instead of the whole image, in compiled code. Numba compiles the kernel
once and caches it beside this module (``cache=True``); the first call of a new install compiles it (~2.5 s
on a loaded 2-core machine), later processes load it from the cache.
"""
from __future__ import annotations

import cv2
import numpy as np
from numba import njit

# neighbour (drow, dcol) of bit k; P2..P9 of Zhang and Suen are bits 1, 2, 3, 4, 5, 6, 7, 0
_BIT_OFFSETS = ((-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1), (0, -1))
_NAMES = ('NW', 'N', 'NE', 'E', 'SE', 'S', 'SW', 'W')


def _neighbours(code: int) -> dict:
    return {name: (code >> k) & 1 for k, name in enumerate(_NAMES)}


def zhang_suen_removable(code: int) -> int:
    """Zhang and Suen's deletion rule with Lü and Wang's 3 <= B(P) for neighbourhood ``code``: bit 1 set if
    P is deleted in the first sub-iteration, bit 2 in the second."""
    v = _neighbours(code)
    p = [v['N'], v['NE'], v['E'], v['SE'], v['S'], v['SW'], v['W'], v['NW']]      # P2 .. P9
    p2, p4, p6, p8 = p[0], p[2], p[4], p[6]
    b = sum(p)
    a = sum(1 for i in range(8) if p[i] == 0 and p[(i + 1) % 8] == 1)
    if not (3 <= b <= 6 and a == 1):
        return 0
    first = p2 * p4 * p6 == 0 and p4 * p6 * p8 == 0
    second = p2 * p4 * p8 == 0 and p2 * p6 * p8 == 0
    return int(first) | 2 * int(second)


def staircase_removable(code: int) -> int:
    """Holt et al.'s staircase removal for neighbourhood ``code``: bit 1 set if P is deleted in the north
    pass, bit 2 in the south pass."""
    v = _neighbours(code)

    def corner(n, ne, nw, s, sw, se):
        return bool(v[n] and ((v['E'] and not v[ne] and not v[sw] and (not v['W'] or not v[s]))
                              or (v['W'] and not v[nw] and not v[se] and (not v['E'] or not v[s]))))
    north = corner('N', 'NE', 'NW', 'S', 'SW', 'SE')
    south = corner('S', 'SE', 'SW', 'N', 'NW', 'NE')
    return int(north) | 2 * int(south)


ZHANG_SUEN_TABLE = np.array([zhang_suen_removable(c) for c in range(256)], dtype=np.uint8)
STAIRCASE_TABLE = np.array([staircase_removable(c) for c in range(256)], dtype=np.uint8)


def zhang_suen_thinning(mask: np.ndarray) -> np.ndarray:
    """Skeleton (bool, same shape) of a 2-D binary ``mask``: Zhang-Suen thinning (Lü and Wang's bound),
    then Holt et al.'s staircase removal (see the module docstring). Pixels outside the image count as
    background."""
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f'thinning needs a 2-D mask, got shape {mask.shape}')
    padded = np.zeros((mask.shape[0] + 2, mask.shape[1] + 2), dtype=np.uint8)
    padded[1:-1, 1:-1] = mask if mask.dtype == bool else mask != 0     # (bool: no temporary)
    # the object pixels with a background 8-neighbour: those that a 3 x 3 erosion removes
    eroded = cv2.erode(padded, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_CONSTANT, borderValue=0)
    boundary = np.flatnonzero(padded > eroded)
    _thin(padded, boundary, int(np.count_nonzero(padded)), ZHANG_SUEN_TABLE, STAIRCASE_TABLE)
    return padded[1:-1, 1:-1].view(bool)


@njit(cache=True, nogil=True)
def _delete_pass(flat, offsets, boundary, n, listed, deleted, table, bit):
    """One parallel pass: delete the listed pixels whose neighbourhood has ``bit`` in ``table`` (all
    decided on the image before the pass), then update the boundary list; returns (new list length,
    number deleted)."""
    k = 0
    m = 0
    for i in range(n):
        p = boundary[i]
        code = 0
        for b in range(8):
            code |= flat[p + offsets[b]] << b
        if table[code] & bit:
            deleted[k] = p
            k += 1
            listed[p] = 0
        else:                           # kept: stays on the list (m <= i, so the list is compacted in place)
            boundary[m] = p
            m += 1
    for j in range(k):
        flat[deleted[j]] = 0
    for j in range(k):                  # add the object pixels the deletions exposed
        p = deleted[j]
        for o in offsets:
            q = p + o
            if flat[q] and not listed[q]:
                listed[q] = 1
                boundary[m] = q
                m += 1
    return m, k


@njit(cache=True, nogil=True)
def _thin(image, initial_boundary, n_object, thinning_table, staircase_table):
    """Thin a 0/1 uint8 image with a zero border in place (see the module docstring), starting from the
    flat indices of its boundary pixels; ``n_object``: its number of object pixels (every pixel enters the
    boundary list at most once)."""
    n_cols = image.shape[1]
    flat = image.ravel()
    # flat offsets of the neighbours NW, N, NE, E, SE, S, SW, W (bit k has weight 2**k)
    offsets = np.array([-n_cols - 1, -n_cols, -n_cols + 1, 1, n_cols + 1, n_cols, n_cols - 1, -1])
    listed = np.zeros(flat.size, dtype=np.uint8)
    boundary = np.empty(max(n_object, 1), dtype=np.int64)
    n = initial_boundary.size
    for i in range(n):
        boundary[i] = initial_boundary[i]
        listed[initial_boundary[i]] = 1
    deleted = np.empty(max(n_object, 1), dtype=np.int64)
    changed = True
    while changed:
        changed = False
        for sub_iteration in (1, 2):
            n, k = _delete_pass(flat, offsets, boundary, n, listed, deleted, thinning_table, sub_iteration)
            changed = changed or k > 0
    for staircase_pass in (1, 2):
        n, k = _delete_pass(flat, offsets, boundary, n, listed, deleted, staircase_table, staircase_pass)
