"""Skeleton graph: a binary mask's skeleton as ends, junctions and the pixel chains between them.

The skeleton comes from Zhang-Suen thinning (:mod:`.thinning`: with Lü and Wang's bound and Holt et al.'s
staircase removal, compiled). Every skeleton pixel with three or more 8-neighbours is a junction pixel;
8-connected junction pixels form one junction node. Removing the junction pixels leaves simple 8-connected
chains, the edges, each ordered from one node to the other. Chains without any end or junction are closed loops.

Units are pixels; points are (row, col) floats, integer values at pixel centres.
Then :func:`prune_spurs` removes the short end branches that thinning leaves at flat ends and on boundary
noise, :func:`dissolve_pass_through_junctions` joins chains through junctions left with two branches, and
:func:`remove_small_parts` drops specks. mBEST (Choi et al. 2023, sec. III-A/B) does the same three steps
on the pixel level; here they are graph operations on a few dozen nodes, so they cost microseconds.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numba import njit

from rod_deploy.perception.centreline import path_length
from rod_deploy.perception.thinning import zhang_suen_thinning

END = 'end'
JUNCTION = 'junction'

# 8-neighbour offsets (drow, dcol)
_OFFSETS = np.array([(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)], dtype=np.int64)


@dataclass
class Node:
    """An end (one branch) or a junction (three or more branches) of the skeleton."""
    kind: str
    position: np.ndarray                         # (row, col) [px]: end pixel or junction-pixel centroid
    edges: list = field(default_factory=list)    # incident branches as (edge id, side), side 0 = edge's u end


@dataclass
class Edge:
    """A chain of skeleton pixels from node ``u`` to node ``v`` (both -1 for a closed loop)."""
    points: np.ndarray    # (n, 2) float (row, col) [px], ordered from u to v
    u: int
    v: int

    @property
    def closed(self) -> bool:
        return self.u < 0

    def length_px(self) -> float:
        """Arc length [px] (cached: an edge's points never change)."""
        if self._length is None:
            self._length = path_length(self.points)
        return self._length

    _length: float | None = field(default=None, repr=False, compare=False)


@dataclass
class SkeletonGraph:
    """Nodes and edges; removed ones are set to ``None`` so that ids stay stable."""
    nodes: list
    edges: list
    shape: tuple

    def live_edges(self):
        return [(i, e) for i, e in enumerate(self.edges) if e is not None]

    def live_nodes(self):
        return [(i, n) for i, n in enumerate(self.nodes) if n is not None]

    def degree(self, node_id: int) -> int:
        return len(self.nodes[node_id].edges)

    def edge_end_at(self, edge_id: int, side: int) -> int:
        e = self.edges[edge_id]
        return e.u if side == 0 else e.v

    def branch_points(self, edge_id: int, side: int) -> np.ndarray:
        """The edge's points ordered away from the node at ``side`` (0: from u, 1: from v)."""
        pts = self.edges[edge_id].points
        return pts if side == 0 else pts[::-1]

    def remove_edge(self, edge_id: int):
        e = self.edges[edge_id]
        for side, nid in ((0, e.u), (1, e.v)):
            if nid >= 0 and self.nodes[nid] is not None:
                self.nodes[nid].edges = [b for b in self.nodes[nid].edges if b != (edge_id, side)]
        self.edges[edge_id] = None

    def add_edge(self, points: np.ndarray, u: int, v: int) -> int:
        eid = len(self.edges)
        self.edges.append(Edge(np.asarray(points, dtype=np.float64), u, v))
        if u >= 0:
            self.nodes[u].edges.append((eid, 0))
        if v >= 0:
            self.nodes[v].edges.append((eid, 1))
        return eid


def skeleton_of(mask: np.ndarray) -> np.ndarray:
    """Skeleton (bool) of a binary mask by Zhang-Suen thinning (:func:`.thinning.zhang_suen_thinning`), of the
    mask's bounding box."""
    mask = np.asarray(mask, dtype=bool)
    out = np.zeros(mask.shape, dtype=bool)
    if not mask.size:
        return out
    c0, r0, w, h = cv2.boundingRect(mask.view(np.uint8))        # the object pixels' bounding box
    if w == 0 or h == 0:
        return out
    r1, c1 = r0 + h, c0 + w
    out[r0:r1, c0:c1] = zhang_suen_thinning(mask[r0:r1, c0:c1])
    return out


def build_skeleton_graph(skeleton: np.ndarray) -> SkeletonGraph:
    """Turn a one-pixel-wide skeleton into a :class:`SkeletonGraph`.

    Works on the skeleton pixels and their bounding box only, so the cost grows with the skeleton, not
    the image; one compiled walk orders the chains."""
    sk = np.asarray(skeleton, dtype=bool)
    shape = sk.shape
    flat = np.flatnonzero(sk)                   # (much faster than np.nonzero on a sparse bool image)
    rows, cols = np.divmod(flat, shape[1])
    graph = SkeletonGraph([], [], shape)
    n = rows.size
    if n == 0:
        return graph
    # neighbours (pixel numbers, -1: none), compiled
    nb = _neighbour_table(flat, shape[1], _OFFSETS)
    valid = nb >= 0
    junction = valid.sum(axis=1) >= 3

    # junction pixels -> junction nodes (8-connected clusters, numbered in pixel order)
    jl = np.full(n, -1, dtype=np.int64)
    jpix = np.flatnonzero(junction)
    if jpix.size:
        a_idx, k_idx = np.nonzero(valid[jpix])
        dst = nb[jpix[a_idx], k_idx]
        both = junction[dst]
        ordinal = np.full(n, -1, dtype=np.int64)
        ordinal[jpix] = np.arange(jpix.size)
        n_nodes, lab = _cluster(jpix.size, a_idx[both].tolist(), ordinal[dst[both]].tolist())
        jl[jpix] = lab
        cnt = np.bincount(lab, minlength=n_nodes)
        mr = np.bincount(lab, weights=rows[jpix], minlength=n_nodes) / cnt
        mc = np.bincount(lab, weights=cols[jpix], minlength=n_nodes) / cnt
        for k in range(n_nodes):
            graph.nodes.append(Node(JUNCTION, np.array([mr[k], mc[k]])))

    # per pixel: its two largest chain (non-junction) neighbours (-1: none), their count, and the largest and
    # smallest label of an adjacent junction node (-1 / int64 max: none)
    first, second, n_nb, touch, touch2 = _chain_links(nb, junction, jl)
    chain = ~junction
    order, bounds, closed = _walk_chains(first, second, np.flatnonzero(chain & (n_nb <= 1)), ~chain)
    points = np.stack([rows, cols], axis=1).astype(np.float64)
    for k in range(len(closed)):
        chain_order = order[bounds[k]:bounds[k + 1]]
        if not closed[k]:
            _add_chain(graph, chain_order, points, touch, touch2)
            continue
        pts = points[chain_order]
        if len(chain_order) > 2:
            pts = np.concatenate([pts, pts[:1]])
        graph.add_edge(pts, -1, -1)
    return graph


@njit(cache=True, nogil=True)
def _neighbour_table(flat, width, offsets):
    """(n, 8) pixel numbers of the 8-neighbours (``offsets`` order) of the skeleton pixels (``flat``: their
    ascending flat indices in an image ``width`` pixels wide), -1 where there is none. The flat index of
    each neighbour direction grows with the pixel number, so one pointer per direction walks ``flat`` once
    (no index image of the skeleton's bounding box)."""
    n = flat.size
    nb = np.empty((n, 8), dtype=np.int64)
    pointer = np.zeros(8, dtype=np.int64)
    for i in range(n):
        c = flat[i] % width
        for k in range(8):
            nb[i, k] = -1
            if c + offsets[k, 1] < 0 or c + offsets[k, 1] >= width:
                continue
            target = flat[i] + offsets[k, 0] * width + offsets[k, 1]
            j = pointer[k]
            while j < n and flat[j] < target:
                j += 1
            pointer[k] = j
            if j < n and flat[j] == target:
                nb[i, k] = j
    return nb


@njit(cache=True, nogil=True)
def _chain_links(nb, junction, jl):
    """For each pixel: the largest and second largest number of a non-junction neighbour (-1: none), how many
    there are, and the largest and smallest junction node label among its neighbours (-1 and int64 max if
    none)."""
    n = nb.shape[0]
    first = np.full(n, -1, dtype=np.int64)
    second = np.full(n, -1, dtype=np.int64)
    n_nb = np.zeros(n, dtype=np.int64)
    touch = np.full(n, -1, dtype=np.int64)
    touch2 = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)
    for i in range(n):
        for k in range(8):
            q = nb[i, k]
            if q < 0:
                continue
            if junction[q]:
                touch[i] = max(touch[i], jl[q])
                touch2[i] = min(touch2[i], jl[q])
            else:
                n_nb[i] += 1
                if q > first[i]:
                    second[i] = first[i]
                    first[i] = q
                elif q > second[i]:
                    second[i] = q
    return first, second, n_nb, touch, touch2


def _cluster(n: int, a: list, b: list):
    """Connected components of ``n`` items joined by the pairs (a[i], b[i]): (count, label per item),
    labels numbered in the order of each component's first item."""
    parent = list(range(n))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in zip(a, b):
        ri, rj = root(i), root(j)
        if ri != rj:
            parent[max(ri, rj)] = min(ri, rj)
    labels, first_seen = [], {}
    for i in range(n):
        labels.append(first_seen.setdefault(root(i), len(first_seen)))
    return len(first_seen), np.array(labels, dtype=np.int64)


@njit(cache=True, nogil=True)
def _walk_chains(first, second, ends, visited):
    """Pixel indices of every chain, walked from each unvisited end in turn, then what is left (closed
    loops) from its lowest unvisited pixel. Chain pixels have at most two chain neighbours (``first``,
    ``second``; -1: none), so a walk only has to avoid going back, and stops at the chain's end or back
    at its start. Returns (indices of all chains one after the other, chain k's slice bounds
    [bounds[k], bounds[k + 1]), closed flag per chain); ``visited`` is updated."""
    n = first.size
    order = np.empty(n, dtype=np.int64)
    bounds = [0]
    closed = []
    m = 0
    for phase in range(2):
        starts = ends if phase == 0 else np.arange(n)
        for start in starts:
            if visited[start]:
                continue
            order[m] = start
            m += 1
            visited[start] = True
            prev, cur = -1, start
            while True:
                nxt = first[cur]
                if nxt == prev:
                    nxt = second[cur]
                if nxt < 0 or nxt == start:
                    break
                order[m] = nxt
                m += 1
                visited[nxt] = True
                prev, cur = cur, nxt
            bounds.append(m)
            closed.append(phase == 1)
    return order[:m], np.array(bounds), np.array(closed)


def _add_chain(graph, order, points, touch, touch2):
    """Add one open chain (pixel numbers ``order``; ``points``: (row, col) of every pixel) as an edge, creating
    end nodes where it touches no junction."""
    a, b = order[0], order[-1]
    ja, jb = int(touch[a]), int(touch[b])
    if a == b and touch2[a] != np.iinfo(np.int64).max and touch2[a] != ja:
        jb = int(touch2[a])                                  # one-pixel bridge between two junctions
    pts = points[order]
    ends = []
    for j, at in ((ja, 0), (jb, -1)):
        if j >= 0:
            ends.append((j, graph.nodes[j].position))
        else:
            graph.nodes.append(Node(END, pts[at].copy()))
            ends.append((len(graph.nodes) - 1, None))
    (u, upos), (v, vpos) = ends
    # chains start and end at their node's position (junction centroid), so joined paths are continuous
    parts = []
    if upos is not None:
        parts.append(upos[None])
    parts.append(pts)
    if vpos is not None:
        parts.append(vpos[None])
    graph.add_edge(np.concatenate(parts) if len(parts) > 1 else pts, u, v)


def remove_node_if_isolated(graph: SkeletonGraph, node_id: int):
    if graph.nodes[node_id] is not None and not graph.nodes[node_id].edges:
        graph.nodes[node_id] = None


def prune_spurs(graph: SkeletonGraph, max_length_px: float, max_rounds: int = 3) -> int:
    """Remove end branches shorter than ``max_length_px`` that hang off a junction (thinning artefacts at
    flat ends and boundary bumps), and loops from a junction back to itself shorter than that (the
    skeleton around a pinhole in the mask, e.g. a speck of background caught where two rods meet: a rod's
    own loop is at least pi w round). At a junction where every branch is short, the longest stays.
    Returns the number of edges removed."""
    removed = 0
    for _ in range(max_rounds):
        spurs_at: dict[int, list[int]] = {}
        loops = 0
        for eid, e in graph.live_edges():
            if e.u == e.v and not e.closed and e.length_px() < max_length_px:
                graph.remove_edge(eid)
                loops += 1
                node = graph.nodes[e.u]
                if len(node.edges) == 1:
                    node.kind = END
                remove_node_if_isolated(graph, e.u)
                continue
            if e.closed or e.u == e.v:
                continue
            ku, kv = graph.nodes[e.u].kind, graph.nodes[e.v].kind
            if (ku == END) == (kv == END):
                continue
            if e.length_px() >= max_length_px:
                continue
            junction = e.v if ku == END else e.u
            spurs_at.setdefault(junction, []).append(eid)
        removed += loops
        if not spurs_at and not loops:
            break
        for junction, spurs in spurs_at.items():
            incident = {eid for eid, _ in graph.nodes[junction].edges}
            if incident <= set(spurs):     # everything here is short: keep the longest
                spurs = sorted(spurs, key=lambda i: graph.edges[i].length_px())[:-1]
            for eid in spurs:
                e = graph.edges[eid]
                end_node = e.u if graph.nodes[e.u].kind == END else e.v
                graph.remove_edge(eid)
                remove_node_if_isolated(graph, end_node)
                removed += 1
            node = graph.nodes[junction]
            if node is not None and len(node.edges) == 1:
                node.kind = END
        dissolve_pass_through_junctions(graph)
    return removed


def dissolve_pass_through_junctions(graph: SkeletonGraph):
    """Join the two edges at every node with exactly two branches (leftovers of pruning or thinning
    artefacts), so that every remaining junction has three or more branches."""
    for nid, node in graph.live_nodes():
        if len(node.edges) != 2:
            continue
        (ea, sa), (eb, sb) = node.edges
        if ea == eb:                        # a loop through this node only: make it a closed edge
            pts = graph.edges[ea].points
            graph.remove_edge(ea)
            graph.add_edge(pts, -1, -1)
            graph.nodes[nid] = None
            continue
        pa = graph.branch_points(ea, sa)[::-1]       # ends at the node
        pb = graph.branch_points(eb, sb)             # starts at the node
        u = graph.edge_end_at(ea, 1 - sa)
        v = graph.edge_end_at(eb, 1 - sb)
        pts = np.vstack([pa, pb[1:]])
        graph.remove_edge(ea)
        graph.remove_edge(eb)
        graph.nodes[nid] = None
        graph.add_edge(pts, u, v)


def remove_small_parts(graph: SkeletonGraph, min_length_px: float):
    """Drop isolated edges (end to end, or closed) shorter than ``min_length_px``: specks, not objects."""
    for eid, e in graph.live_edges():
        isolated = e.closed or (graph.nodes[e.u].kind == END and graph.nodes[e.v].kind == END)
        if isolated and e.length_px() < min_length_px:
            u, v = e.u, e.v
            graph.remove_edge(eid)
            for nid in (u, v):
                if nid >= 0:
                    remove_node_if_isolated(graph, nid)
