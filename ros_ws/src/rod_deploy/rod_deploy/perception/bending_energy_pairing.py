"""Pairing of the branches at a crossing by minimal bending energy (mBEST, Choi et al. 2023, sec. III-C).

A crossing is a cluster of skeleton junctions: one junction where two strands cross steeply, or two
three-way junctions joined by a short chain (the shared overlap) where they cross at a shallow angle.
Each branch leaving the cluster gets an anchor a distance ``skip_px`` out along it (beyond the part of the
skeleton that the junction bends) and a unit tangent pointing into the crossing. Joining branch i to
branch j by the polyline (a_i - t_i, a_i, a_j, a_j - t_j) costs the discrete bending energy of its two
interior vertices (discrete elastic rods, Bergou et al. 2008):

    E_ij = sum_k (2 tan(phi_k / 2))^2 / |a_j - a_i|,

phi_1 the turn from t_i onto the chord a_j - a_i, phi_2 the turn from the chord onto -t_j. The pairing of
all branches with the least total energy is chosen (every perfect matching is enumerated for up to eight
branches; with an odd count one branch is left to end at the crossing, e.g. a rod end touching another
rod). Units: pixels.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations

import numpy as np

from rod_deploy.perception.skeleton_graph import JUNCTION, SkeletonGraph

MAX_TURN_RAD = np.pi - 1e-3


@dataclass
class Branch:
    """One branch leaving a crossing: ``edge`` entered at its ``side`` end (0: u, 1: v)."""
    edge: int
    side: int
    anchor: np.ndarray        # (row, col) [px] where a connector through the crossing starts
    anchor_index: int         # index of ``anchor`` in the branch's points ordered away from the crossing
    tangent: np.ndarray       # unit (drow, dcol) pointing into the crossing


@dataclass
class Crossing:
    """A cluster of junctions with its branches and their minimal-bending-energy pairing."""
    nodes: list
    internal_edges: list
    branches: list
    centre: np.ndarray                          # (row, col) [px]
    pairs: list = field(default_factory=list)   # (i, j) indices into branches
    energy: float = 0.0

    def unpaired(self):
        paired = {i for p in self.pairs for i in p}
        return [i for i in range(len(self.branches)) if i not in paired]


def find_crossings(graph: SkeletonGraph, short_px: float, y_merge_px: float) -> list:
    """Group junctions into crossings: junctions joined by a chain shorter than ``short_px``, and pairs of
    three-way junctions joined by a chain shorter than ``y_merge_px`` (a shallow X split in two Ys)."""
    junctions = [nid for nid, n in graph.live_nodes() if n.kind == JUNCTION]
    parent = {nid: nid for nid in junctions}

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    internal = set()
    candidates = []
    for eid, e in graph.live_edges():
        if e.closed or e.u == e.v or e.u not in parent or e.v not in parent:
            continue
        length = e.length_px()
        if length < short_px:
            internal.add(eid)
            parent[find(e.u)] = find(e.v)
        elif length < y_merge_px and graph.degree(e.u) == 3 and graph.degree(e.v) == 3:
            candidates.append((length, eid))
    # Y pairs, closest first; each Y joins at most one other Y
    merged = set()
    for _, eid in sorted(candidates):
        e = graph.edges[eid]
        if e.u in merged or e.v in merged or find(e.u) == find(e.v):
            continue
        merged.update((e.u, e.v))
        internal.add(eid)
        parent[find(e.u)] = find(e.v)

    groups: dict[int, list] = {}
    for nid in junctions:
        groups.setdefault(find(nid), []).append(nid)
    crossings = []
    for nodes in groups.values():
        node_set = set(nodes)
        inner = sorted({eid for nid in nodes for eid, _ in graph.nodes[nid].edges if eid in internal})
        branches = [(eid, side) for nid in nodes for eid, side in graph.nodes[nid].edges if eid not in internal]
        centre = np.mean([graph.nodes[nid].position for nid in nodes], axis=0)
        crossings.append(Crossing(nodes=sorted(node_set), internal_edges=inner,
                                  branches=branches, centre=centre))
    return crossings


def branch_geometry(points: np.ndarray, skip_px: float, fit_px: float, max_fraction: float = 0.45):
    """Anchor index and inward unit tangent of a branch whose ``points`` start at the crossing.

    The anchor sits ``skip_px`` of arc length out (at most ``max_fraction`` of the branch, so that the two
    ends of a short loop keep distinct anchors); the tangent is the principal direction of the next
    ``fit_px`` of arc, oriented towards the crossing.
    """
    seg = np.hypot(*np.diff(points, axis=0).T) if len(points) > 1 else np.zeros(0)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    skip = min(skip_px, max_fraction * total)
    i0 = int(np.searchsorted(s, skip))
    i0 = min(i0, len(points) - 1)
    i1 = int(np.searchsorted(s, s[i0] + fit_px))
    i1 = min(max(i1, i0 + 1), len(points) - 1)
    if i1 <= i0:    # a branch of one point: direction from the crossing
        i0 = max(0, len(points) - 1)
        d = points[0] - points[-1] if len(points) > 1 else np.array([0.0, 1.0])
    else:
        section = points[i0:i1 + 1]
        centred = section - section.mean(axis=0)
        _, _, vt = np.linalg.svd(centred, full_matrices=False)
        d = vt[0]
        if np.dot(d, points[i0] - points[i1]) < 0:
            d = -d
    norm = np.linalg.norm(d)
    d = d / norm if norm > 0 else np.array([0.0, 1.0])
    return i0, d


def attach_branch_geometry(graph: SkeletonGraph, crossing: Crossing, skip_px: float, fit_px: float):
    """Replace ``crossing.branches`` (edge, side) tuples by :class:`Branch` objects."""
    out = []
    for eid, side in crossing.branches:
        pts = graph.branch_points(eid, side)
        i0, t = branch_geometry(pts, skip_px, fit_px)
        out.append(Branch(eid, side, pts[i0].copy(), i0, t))
    crossing.branches = out


def _turn(a: np.ndarray, b: np.ndarray) -> float:
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na == 0 or nb == 0:
        return 0.0
    c = float(np.clip(np.dot(a, b) / (na * nb), -1.0, 1.0))
    return min(float(np.arccos(c)), MAX_TURN_RAD)


def pair_energy(bi: Branch, bj: Branch) -> float:
    """Discrete bending energy [1/px] of joining branch ``bi`` to branch ``bj`` through the crossing."""
    chord = bj.anchor - bi.anchor
    d = float(np.linalg.norm(chord))
    if d < 1e-9:
        phis = [_turn(bi.tangent, -bj.tangent)]
        d = 1.0
    else:
        phis = [_turn(bi.tangent, chord), _turn(chord, -bj.tangent)]
    return sum((2.0 * np.tan(phi / 2.0)) ** 2 for phi in phis) / d


def _perfect_matchings(items):
    if not items:
        yield []
        return
    first, rest = items[0], items[1:]
    for k in range(len(rest)):
        for m in _perfect_matchings(rest[:k] + rest[k + 1:]):
            yield [(first, rest[k])] + m


def minimal_energy_pairing(branches: list, max_exhaustive: int = 8):
    """Pairs (i, j) of branch indices with the least total bending energy, and that energy.
    With an odd number of branches one is left unpaired."""
    n = len(branches)
    if n < 2:
        return [], 0.0
    energy = np.full((n, n), np.inf)
    for i, j in combinations(range(n), 2):
        energy[i, j] = energy[j, i] = pair_energy(branches[i], branches[j])
    if n <= max_exhaustive:
        best, best_e = [], np.inf
        leave_out = [None] if n % 2 == 0 else list(range(n))
        for skip in leave_out:
            items = [i for i in range(n) if i != skip]
            for m in _perfect_matchings(items):
                e = sum(energy[i, j] for i, j in m)
                if e < best_e:
                    best, best_e = m, e
        return best, float(best_e)
    # many branches (a tangle): greedy, cheapest pair first
    pairs, used, total = [], set(), 0.0
    for e, i, j in sorted((energy[i, j], i, j) for i, j in combinations(range(n), 2)):
        if i in used or j in used:
            continue
        pairs.append((i, j))
        used.update((i, j))
        total += e
    return pairs, float(total)


def pair_crossings(graph: SkeletonGraph, crossings: list, skip_px: float, fit_px: float):
    """Attach branch geometry to every crossing and pair its branches by minimal bending energy."""
    for c in crossings:
        attach_branch_geometry(graph, c, skip_px, fit_px)
        c.pairs, c.energy = minimal_energy_pairing(c.branches)
    return crossings
