"""Traversal of the paired skeleton graph into one ordered centreline per object.

Each object starts at a free end (or, for a closed loop, anywhere) and follows its chain; at a crossing it
leaves its branch at the anchor, follows a cubic Hermite connector (tangents from the branches) to the
anchor of the paired branch and continues there, until it reaches an end, an unpaired branch or its own
start (closed loop). The shared chains inside a crossing (internal edges) belong to no object. Every pass
through a crossing is recorded, so that the crossing's over/under order can be decided afterwards.
Units: pixels, points (row, col).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rod_deploy.perception.bending_energy_pairing import Crossing
from rod_deploy.perception.skeleton_graph import END, SkeletonGraph


@dataclass
class TracedObject:
    """An ordered centreline; ``passes`` lists (crossing id, first, last) index ranges of its connectors."""
    points: np.ndarray
    closed: bool = False
    passes: list = field(default_factory=list)

    def length_px(self) -> float:
        if len(self.points) < 2:
            return 0.0
        return float(np.sum(np.hypot(*np.diff(self.points, axis=0).T)))


def hermite_connector(p0, t0, p1, t1, step_px: float = 1.0) -> np.ndarray:
    """Points of the cubic Hermite curve from ``p0`` (direction ``t0``) to ``p1`` (direction ``t1``), tangent
    magnitudes equal to the chord length; both end points included."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = float(np.linalg.norm(p1 - p0))
    n = max(2, int(np.ceil(d / step_px)) + 1)
    s = np.linspace(0.0, 1.0, n)[:, None]
    h00 = 2 * s ** 3 - 3 * s ** 2 + 1
    h10 = s ** 3 - 2 * s ** 2 + s
    h01 = -2 * s ** 3 + 3 * s ** 2
    h11 = s ** 3 - s ** 2
    return h00 * p0 + h10 * (d * np.asarray(t0)) + h01 * p1 + h11 * (d * np.asarray(t1))


def trace_objects(graph: SkeletonGraph, crossings: list) -> list:
    """Ordered centrelines of all objects (see module docstring)."""
    # (edge, side) -> (crossing id, branch index) for every branch at a crossing
    at_crossing = {}
    internal = set()
    for cid, c in enumerate(crossings):
        internal.update(c.internal_edges)
        for bi, b in enumerate(c.branches):
            at_crossing[(b.edge, b.side)] = (cid, bi)
    partner = {}
    for cid, c in enumerate(crossings):
        for i, j in c.pairs:
            partner[(cid, i)] = j
            partner[(cid, j)] = i

    used = set()
    objects = []

    def anchor_index(eid, side):
        hit = at_crossing.get((eid, side))
        if hit is None:
            return 0
        return crossings[hit[0]].branches[hit[1]].anchor_index

    def walk(start_edge, start_side, closed_possible):
        pieces, passes = [], []
        eid, entry = start_edge, start_side
        n_points = 0
        closed = False
        while True:
            used.add(eid)
            pts = graph.branch_points(eid, entry)         # ordered from the entry end
            a = anchor_index(eid, entry)
            b = len(pts) - 1 - anchor_index(eid, 1 - entry)
            if b < a:                                      # anchors cross on a very short chain
                a = b = (a + b) // 2
            seg = pts[a:b + 1]
            pieces.append(seg)
            n_points += len(seg)
            exit_side = 1 - entry
            hit = at_crossing.get((eid, exit_side))
            if hit is None:
                break
            cid, bi = hit
            bj = partner.get((cid, bi))
            if bj is None:
                break
            c: Crossing = crossings[cid]
            nxt = c.branches[bj]
            conn = hermite_connector(c.branches[bi].anchor, c.branches[bi].tangent, nxt.anchor, -nxt.tangent)
            inner = conn[1:-1]
            passes.append((cid, n_points - 1, n_points + len(inner)))
            pieces.append(inner)
            n_points += len(inner)
            if closed_possible and (nxt.edge, nxt.side) == (start_edge, start_side):
                closed = True
                break
            if nxt.edge in used:                           # should not happen: a pairing reused an edge
                break
            eid, entry = nxt.edge, nxt.side
        points = np.vstack([p for p in pieces if len(p)])
        if closed:
            points = np.vstack([points, points[:1]])
        return TracedObject(points, closed, passes)

    # open objects from free ends, then from unpaired branches at crossings
    starts = []
    for eid, e in graph.live_edges():
        if eid in internal or e.closed:
            continue
        for side, nid in ((0, e.u), (1, e.v)):
            if graph.nodes[nid].kind == END:
                starts.append((0, eid, side))
            elif (eid, side) in at_crossing:
                cid, bi = at_crossing[(eid, side)]
                if (cid, bi) not in partner:
                    starts.append((1, eid, side))
    for _, eid, side in sorted(starts):
        if eid not in used:
            objects.append(walk(eid, side, closed_possible=False))
    # closed loops: plain closed chains, and cycles through crossings
    for eid, e in graph.live_edges():
        if eid in used or eid in internal:
            continue
        if e.closed:
            used.add(eid)
            objects.append(TracedObject(e.points.copy(), True, []))
        else:
            objects.append(walk(eid, 0, closed_possible=True))
    return objects
