"""Pairing of the branches at a crossing by minimal bending energy (mBEST, Choi et al. 2023, sec. III-C).

A crossing is a cluster of skeleton junctions: one junction where two strands cross steeply, two
three-way junctions joined by a short chain (the shared overlap) where they cross at a shallow angle or by
a chain that carries both rods side by side (a lens between two crossings), or several junctions around
the overlap of three strands (see :func:`find_crossings`).
Each branch leaving the cluster gets an anchor a distance ``skip_px`` out along it (beyond the part of the
skeleton that the junction bends; at a shallow crossing at least ``SPLAY_FRACTION`` of the overlap; at
least half the width of the widest rod through the crossing plus 2 px, so that a thin rod's anchors lie
outside a thick rod under or over it) and a unit tangent pointing into the crossing. Joining branch i to
branch j by the polyline (a_i - t_i, a_i, a_j, a_j - t_j) costs the discrete bending energy of its two
interior vertices (discrete elastic rods, Bergou et al. 2008):

    E_ij = sum_k (2 tan(phi_k / 2))^2 / |a_j - a_i|,

phi_1 the turn from t_i onto the chord a_j - a_i, phi_2 the turn from the chord onto -t_j. The pairing of
all branches with the least total energy is chosen (every perfect matching is enumerated for up to eight
branches; with an odd count one branch is left to end at the crossing, e.g. a rod end touching another
rod). Where colour is known, joining two branches whose colours clearly differ (CIELAB a*b* distance above
``min_colour_separation``, unless they are one hue, the paler one at least 0.6 times as chromatic: one paint
in light and the shadow of the strand above, :func:`paints_differ`) costs ``colour_penalty`` more, about a
150-degree turn: rods do not change colour in a crossing, while the skeleton of a shallow or tangential
crossing can make the wrong pairing the straighter one. Joining the two ends of one chain into a closed loop costs ``loop_penalty`` more: where a
stroke ends tangentially on itself (a letter b, a loop closing onto its lead-in) both pairings are
straight, and the open curve is the likelier reading. Across a chain of two rods side by side the rods'
sides decide instead (:func:`same_side_pairing`): through a long lens every pairing is about as straight.
Units: pixels.
"""
from __future__ import annotations

import heapq
import math
from functools import lru_cache
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
from numba import njit

from rod_deploy.perception.centreline import _arc_length, path_length
from rod_deploy.perception.crossing_order import median0
from rod_deploy.perception.fma import fma64
from rod_deploy.perception.skeleton_graph import JUNCTION, SkeletonGraph

MAX_TURN_RAD = np.pi - 1e-3
MIN_ARM_FRACTION = 0.25  # a shallow crossing's four arms are at least this fraction of its overlap long
SPLAY_FRACTION = 0.2      # branch anchors of a shallow crossing at least this fraction of its overlap out
SHADE_HUE_DEG = 8.0       # two chromatic colours within this many degrees of hue ...
SHADE_CHROMA = 0.6        # ... and this fraction of chroma: one paint in light and shade (paints_differ)


@dataclass
class Branch:
    """One branch leaving a crossing: ``edge`` entered at its ``side`` end (0: u, 1: v)."""
    edge: int
    side: int
    anchor: np.ndarray        # (row, col) [px] where a connector through the crossing starts
    anchor_index: int         # index of ``anchor`` in the branch's points ordered away from the crossing
    tangent: np.ndarray       # unit (drow, dcol) pointing into the crossing
    colour: np.ndarray | None = None   # CIELAB (a*, b*) of the branch beyond the anchor, if known


@dataclass
class Crossing:
    """A cluster of junctions with its branches and their minimal-bending-energy pairing."""
    nodes: list
    internal_edges: list
    branches: list
    centre: np.ndarray                          # (row, col) [px]
    pairs: list = field(default_factory=list)   # (i, j) indices into branches
    overlap_px: float = 0.0                     # length of the shared chain of a shallow crossing (0: none)
    energy: float = 0.0
    width_px: float = 0.0                       # the widest rod through the crossing (0: not measured)
    doubled_edge: int | None = None             # the shared chain, if it carries two rods side by side

    def unpaired(self):
        paired = {i for p in self.pairs for i in p}
        return [i for i in range(len(self.branches)) if i not in paired]


def find_crossings(graph: SkeletonGraph, short_px: float, y_merge_px: float, max_branches: int = 8,
                   width_at=None, fit_px: float = 8.0, max_shallow_deg: float = 40.0,
                   shallow_slack: float = 2.0) -> list:
    """Group junctions into crossings.

    Junctions joined by a chain shorter than ``short_px`` form one cluster. A cluster with an odd number
    of branches forces an object end at a junction (one branch is left unpaired), which a rod end
    lying on another rod does, but which is more often half of a crossing the skeleton split in two: a
    shallow X becomes two Ys, three rods crossing near one point become several clusters around it. So
    odd clusters are joined to the nearest other odd cluster reachable along chains of total length below
    ``y_merge_px`` (through even clusters on the way, which join too), closest first, as long as the
    result has at most ``max_branches`` branches.

    Before that, with ``width_at(points)`` (the local rod width [px] at skeleton points), a shallow X split
    into two Ys joined by a longer shared chain is recognised from its geometry: two single three-way
    junctions joined by one chain of length L, at each of which the two other branches diverge by less than
    ``max_shallow_deg`` and leave away from the chain, with L within a factor ``shallow_slack`` of
    w / tan(theta / 2) (w the mean width of the four branches, theta their mean divergence: two strips of
    width w crossing at theta overlap along about that length); and so are two such junctions whose branches
    leave away from a chain as wide as two of them side by side (:func:`_doubled`, any angle): the
    crossing's ``doubled_edge`` is that chain when the rods cross an even number of times along it
    (:func:`overlaps_along`), for :func:`same_side_pairing`. Branch tangents as in :func:`branch_geometry`
    (``skip_px``, ``fit_px``)."""
    junctions = [nid for nid, n in graph.live_nodes() if n.kind == JUNCTION]
    parent = {nid: nid for nid in junctions}

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    internal = set()
    links = []            # chains between two different junctions, not (yet) internal
    chains = []           # all chains between two different junctions (candidates for a shallow overlap)
    for eid, e in graph.live_edges():
        if e.closed or e.u == e.v or e.u not in parent or e.v not in parent:
            continue
        length = e.length_px()
        if length >= short_px:
            chains.append((length, eid))
        if length < short_px:
            internal.add(eid)
            parent[find(e.u)] = find(e.v)
        elif length < y_merge_px:
            links.append((length, eid))

    count = {}            # cluster root -> number of branches
    for nid in junctions:
        r = find(nid)
        count[r] = count.get(r, 0) + sum(1 for eid, _ in graph.nodes[nid].edges if eid not in internal)
    overlaps = {}         # shared chains of shallow crossings -> their length
    doubled = set()       # ... of them those that carry two rods side by side
    if width_at is not None:
        for length, eid, is_doubled in sorted(_shallow_links(graph, chains, find, count, width_at, fit_px,
                                                             max_shallow_deg, shallow_slack)):
            e = graph.edges[eid]
            a, b = find(e.u), find(e.v)
            if a == b or count[a] != 3 or count[b] != 3:
                continue
            internal.add(eid)
            overlaps[eid] = length
            if is_doubled:
                doubled.add(eid)
            parent[a] = b
            count[b] = count.pop(a) + 3 - 2
        links = [(length, eid) for length, eid in links if eid not in internal]
    while True:
        path = _closest_odd_pair(graph, links, find, count, y_merge_px, max_branches)
        if path is None:
            break
        roots = _path_roots(graph, find, path)
        merged = sum(count.pop(r) for r in roots) - 2 * len(path)
        internal.update(path)
        root = roots.pop()
        for r in roots:
            parent[r] = root
        count[root] = merged
        links = [(length, eid) for length, eid in links if eid not in internal]

    groups: dict[int, list] = {}
    for nid in junctions:
        groups.setdefault(find(nid), []).append(nid)
    crossings = []
    for nodes in groups.values():
        node_set = set(nodes)
        inner = sorted({eid for nid in nodes for eid, _ in graph.nodes[nid].edges if eid in internal})
        branches = [(eid, side) for nid in nodes for eid, side in graph.nodes[nid].edges if eid not in internal]
        centre = np.mean([graph.nodes[nid].position for nid in nodes], axis=0)
        pair_of_ys = len(nodes) == 2 and len(inner) == 1 and len(branches) == 4
        crossings.append(Crossing(nodes=sorted(node_set), internal_edges=inner, branches=branches, centre=centre,
                                  doubled_edge=inner[0] if pair_of_ys and inner[0] in doubled else None,
                                  overlap_px=max((overlaps.get(eid, 0.0) for eid in inner), default=0.0),
                                  width_px=0.0 if width_at is None or len(branches) < 4
                                  else _widest_rod(graph, branches, width_at, fit_px)))
    return crossings


def _widest_rod(graph, branches, width_at, fit_px):
    """Width [px] of the widest rod through a crossing: the second largest of its branches' widths (median
    of ``width_at`` - 1 over the stretch from ``fit_px`` to 3 ``fit_px`` out, past the junction's blob; a rod
    gives two branches, so one odd branch, a spur or a rod lying alongside, does not count); 0 if fewer
    than two branches are long enough."""
    lo, hi = int(np.ceil(fit_px)), int(np.ceil(3 * fit_px)) + 1
    widths = sorted(float(median0(width_at(pts[lo:hi]))) - 1.0 for pts in
                    (graph.branch_points(eid, side) for eid, side in branches) if len(pts) >= lo + 3)
    return widths[-2] if len(widths) >= 2 else 0.0


def _shallow_links(graph, chains, find, count, width_at, fit_px, max_deg, slack, min_deg=8.0,
                   max_doubled_factor=12.0):
    """(length, edge id, doubled) of the chains that are the shared overlap of a shallow crossing (see
    :func:`find_crossings`), or carry two rods side by side between two crossings (doubled, :func:`_doubled`).
    The branches' directions are taken from the chain's middle (where the rods cross) to a point well out
    along each branch: next to a Y junction the skeleton splays."""
    out = []
    cos_away = math.cos(math.radians(30.0))
    for length, eid in chains:
        e = graph.edges[eid]
        if count.get(find(e.u)) != 3 or count.get(find(e.v)) != 3 or find(e.u) == find(e.v):
            continue
        middle = e.points[len(e.points) // 2]
        thetas, widths, arm_widths, ok = [], [], [], True
        for nid, other in ((e.u, e.v), (e.v, e.u)):
            node = graph.nodes[nid]
            # single three-way junctions, joined by this chain only (two chains between them: an eye, a rod
            # and its shadow or two rods side by side, not a crossing)
            if len(node.edges) != 3 or any(x != eid and {graph.edges[x].u, graph.edges[x].v} & {e.u, e.v} ==
                                           {e.u, e.v} or graph.edges[x].u == graph.edges[x].v
                                           for x, _ in node.edges):
                ok = False
                break
            chain = graph.nodes[other].position - node.position
            chain = chain / max(float(np.linalg.norm(chain)), 1e-9)
            outward = []
            for beid, side in node.edges:
                if beid == eid:
                    continue
                pts = graph.branch_points(beid, side)
                w = float(median0(width_at(pts[:int(np.ceil(fit_px)) + 1][-max(3, int(fit_px) // 2):])))
                if len(pts) < MIN_ARM_FRACTION * length:   # a spur or a piece of shadow, not a rod's arm
                    break
                far = pts[min(len(pts) - 1, int(0.5 * length + 3.0 * w))]
                d = far - middle
                outward.append(d / max(float(np.linalg.norm(d)), 1e-9))
                widths.append(w)
                lo, hi = int(np.ceil(fit_px)), int(np.ceil(3 * fit_px)) + 1     # past the junction's blob
                arm_widths.append(float(median0(width_at(pts[lo:hi]))) if len(pts) >= lo + 3 else np.inf)
            if len(outward) != 2:
                ok = False
                break
            mean_out = outward[0] + outward[1]
            mean_out = mean_out / max(float(np.linalg.norm(mean_out)), 1e-9)
            # both branches leave away from the chain (not one of them running back along it: an eye)
            if float(np.dot(mean_out, chain)) > -cos_away or max(float(np.dot(o, chain)) for o in outward) > -0.7:
                ok = False
                break
            thetas.append(math.acos(max(-1.0, min(1.0, float(np.dot(outward[0], outward[1]))))))
        if not ok:
            continue
        if _doubled(e.points, arm_widths, width_at, max_doubled_factor):
            # side by side between the two Ys: paired on the same side if the rods cross there an even
            # number of times, else (one crossing along the stretch) by bending energy
            out.append((length, eid, overlaps_along(e.points, arm_widths, width_at) % 2 == 0))
            continue
        theta = max(0.5 * (thetas[0] + thetas[1]), math.radians(min_deg))
        if max(thetas) > math.radians(max_deg):
            continue
        expected = float(np.mean(widths)) / math.tan(0.5 * theta)
        if expected / slack <= length <= slack * expected:
            out.append((length, eid, False))
    return out


def _doubled(points, arm_widths, width_at, max_length_factor, min_sum_fraction=0.8, min_width_factor=1.6,
             min_length_factor=3.0):
    """True if the chain ``points`` between two Y junctions carries two rods lying side by side (a lens
    between two crossings of two rods, or two rods running along each other for a stretch): the mask's width
    along its middle half (median of ``width_at`` - 1) is at least ``min_sum_fraction`` of the sum of the two
    rods' widths (the mean of the pairs of ``arm_widths`` at its two ends, each ``width_at`` - 1 too, measured
    past the junctions' blobs) and
    ``min_width_factor`` times the widest arm, and the chain is ``min_length_factor`` to ``max_length_factor``
    times that width long. A single rod through the chain is no wider than its arms; the chain of a steep X
    split into two Ys is as wide but shorter than wide."""
    n = len(points)
    if n < 4 or len(arm_widths) != 4:
        return False
    arms = [x - 1.0 for x in arm_widths]
    width = float(median0(width_at(points[n // 4:n - n // 4]))) - 1.0
    rods = 0.5 * (arms[0] + arms[1] + arms[2] + arms[3])
    return (width >= min_sum_fraction * rods and width >= min_width_factor * max(arms)
            and min_length_factor * width <= path_length(points) <= max_length_factor * width)


def overlaps_along(points, arm_widths, width_at, single_factor=1.25, skip=2):
    """The number of places along a chain that carries two rods side by side (:func:`_doubled`) where the
    rods overlap, each one a crossing: maximal runs of points (``skip`` points at each end left out: the
    junctions) where the mask's width (``width_at`` - 1, running median of 3) is at most ``single_factor``
    times one rod's width (the median of the four ``arm_widths`` - 1) + 1 px. A lens between two
    crossings narrows to one rod's width at both ends; two rods that come to lie side by side, cross once
    and part again narrow once, in the middle."""
    widths = np.asarray(width_at(points), dtype=np.float64)[skip:len(points) - skip] - 1.0
    if len(widths) < 3:
        return 0
    smooth = np.median(np.lib.stride_tricks.sliding_window_view(widths, 3), axis=1)
    single = float(np.median(np.asarray(arm_widths, dtype=np.float64) - 1.0))
    narrow = smooth <= single_factor * single + 1.0
    return int(narrow[0]) + int(np.count_nonzero(narrow[1:] & ~narrow[:-1]))


def _closest_odd_pair(graph, links, find, count, max_px, max_branches):
    """The shortest path of chains (``links``: (length, edge id)) between two odd clusters, through even
    clusters only, shorter than ``max_px`` in all and leaving at most ``max_branches`` branches when
    merged; None if there is none. Dijkstra from every odd cluster (there are a handful)."""
    adjacent: dict[int, list] = {}
    for length, eid in links:
        e = graph.edges[eid]
        a, b = find(e.u), find(e.v)
        if a != b:
            adjacent.setdefault(a, []).append((length, eid, b))
            adjacent.setdefault(b, []).append((length, eid, a))
    best_path, best_d = None, max_px
    for src in adjacent:
        if count[src] % 2 == 0:
            continue
        dist = {src: 0.0}
        heap = [(0.0, src, ())]
        while heap:
            d, r, path = heapq.heappop(heap)
            if d > dist[r] or d >= best_d:
                continue
            if r != src and count[r] % 2:
                merged = sum(count[x] for x in _path_roots(graph, find, path)) - 2 * len(path)
                if merged <= max_branches:
                    best_path, best_d = path, d
                continue
            for length, eid, nxt in adjacent[r]:
                nd = d + length
                if nd < min(best_d, dist.get(nxt, np.inf)):
                    dist[nxt] = nd
                    heapq.heappush(heap, (nd, nxt, path + (eid,)))
    return best_path


def _path_roots(graph, find, path):
    return {find(x) for eid in path for x in (graph.edges[eid].u, graph.edges[eid].v)}


def branch_geometry(points: np.ndarray, skip_px: float, fit_px: float, max_fraction: float = 0.45):
    """Anchor index and inward unit tangent of a branch whose ``points`` start at the crossing.

    The anchor sits ``skip_px`` of arc length out (at most ``max_fraction`` of the branch, so that the two
    ends of a short loop keep distinct anchors); the tangent is the principal direction of the next
    ``fit_px`` of arc, oriented towards the crossing. (n >= 1, 2) points; compiled (:func:`_branch_geometry`).
    """
    points = np.ascontiguousarray(points[:int(2 * (skip_px + fit_px)) + 3], dtype=np.float64)  # only the start
    if points.ndim != 2 or points.shape[1] != 2 or not len(points):
        raise ValueError(f'expected (n >= 1, 2) branch points, got shape {points.shape}')
    d = np.empty(2)
    return int(_branch_geometry(points, float(skip_px), float(fit_px), float(max_fraction), d)), d


@njit(cache=True, nogil=True)
def _branch_geometry(points, skip_px, fit_px, max_fraction, d):
    """:func:`branch_geometry` into ``d``, returning the anchor index. The numpy formulas' arithmetic (on this
    machine's numpy and OpenBLAS, checked in the tests): arc length as :func:`~.centreline.arc_length`;
    np.searchsorted (left); the section's mean as numpy's mean along axis 0 (running sums / n); its scatter
    ``centred.T @ centred`` as OpenBLAS's running fused multiply-adds; the principal axis theta =
    atan2(2 b, a - c) / 2 (isotropic: the column axis); oriented by the sign of the dot product with
    p[i0] - p[i1] (an fma, as OpenBLAS's ddot); a one-point section: the direction from the crossing,
    normalised by its np.linalg.norm (sqrt of the same fma)."""
    n = points.shape[0]
    s = _arc_length(points)
    skip = min(skip_px, max_fraction * s[n - 1])
    i0 = min(np.searchsorted(s, skip), n - 1)
    i1 = min(max(np.searchsorted(s, s[i0] + fit_px), i0 + 1), n - 1)
    if i1 <= i0:            # a branch of one point: direction from the crossing
        i0 = max(0, n - 1)
        if n > 1:
            d[0], d[1] = points[0, 0] - points[n - 1, 0], points[0, 1] - points[n - 1, 1]
        else:
            d[0], d[1] = 0.0, 1.0
        norm = np.sqrt(fma64(d[1], d[1], d[0] * d[0]))
        if norm > 0:
            d[0], d[1] = d[0] / norm, d[1] / norm
        else:
            d[0], d[1] = 0.0, 1.0
        return i0
    m = i1 + 1 - i0
    mean_r, mean_c = 0.0, 0.0
    for k in range(i0, i1 + 1):
        mean_r += points[k, 0]
        mean_c += points[k, 1]
    mean_r, mean_c = mean_r / m, mean_c / m
    a, b, c = 0.0, 0.0, 0.0
    for k in range(i0, i1 + 1):
        x, y = points[k, 0] - mean_r, points[k, 1] - mean_c
        a = fma64(x, x, a)
        b = fma64(x, y, b)
        c = fma64(y, y, c)
    if b == 0.0:
        d[0], d[1] = (1.0, 0.0) if a > c else (0.0, 1.0)
    else:
        theta = 0.5 * math.atan2(2.0 * b, a - c)
        d[0], d[1] = math.cos(theta), math.sin(theta)
    dr, dc = points[i0, 0] - points[i1, 0], points[i0, 1] - points[i1, 1]
    if fma64(d[1], dc, d[0] * dr) < 0:
        d[0], d[1] = -d[0], -d[1]
    return i0


def attach_branch_geometry(graph: SkeletonGraph, crossings: list, skip_px: float, fit_px: float,
                           colour_of=None):
    """Replace every crossing's ``branches`` (edge, side) tuples by :class:`Branch` objects;
    ``colour_of(points)`` (optional) gives the colour of a stretch of points (all stretches in one batch
    if it has ``batch``)."""
    branches, stretches = [], []
    for crossing in crossings:
        out = []
        # past the Ys of a long overlap (a shallow crossing) the skeleton splays over a longer stretch
        # and past the widest rod through the crossing (a thin rod on a thick one: the thin rod's skeleton
        # bends over the thick rod's half width)
        skip = max(skip_px, SPLAY_FRACTION * crossing.overlap_px, 0.5 * crossing.width_px + 2.0)
        for eid, side in crossing.branches:
            pts = graph.branch_points(eid, side)
            i0, t = branch_geometry(pts, skip, fit_px)
            stretch = pts[i0:i0 + int(np.ceil(fit_px)) + 1]
            stretches.append(stretch if len(stretch) >= 3 else stretch[:0])
            out.append(Branch(eid, side, pts[i0].copy(), i0, t))
        crossing.branches = out
        branches += out
    if colour_of is not None and branches:
        colours = (colour_of.batch(stretches) if hasattr(colour_of, 'batch')
                   else [colour_of(p) if len(p) else None for p in stretches])
        for b, c in zip(branches, colours):
            b.colour = c


def _turn(ax: float, ay: float, bx: float, by: float) -> float:
    """Angle [rad] between two 2-vectors (plain floats: this runs for every branch pair)."""
    na, nb = math.hypot(ax, ay), math.hypot(bx, by)
    if na == 0 or nb == 0:
        return 0.0
    c = max(-1.0, min(1.0, (ax * bx + ay * by) / (na * nb)))
    return min(math.acos(c), MAX_TURN_RAD)


def pair_energy(bi: Branch, bj: Branch) -> float:
    """Discrete bending energy [1/px] of joining branch ``bi`` to branch ``bj`` through the crossing
    (the module docstring's E_ij)."""
    return _pair_energy(_geometry(bi), _geometry(bj))


def _geometry(b: Branch) -> tuple:
    """(anchor row, col, tangent row, col) as plain floats (the energies of all pairs take them many times)."""
    return (*b.anchor.tolist(), *b.tangent.tolist())


def _pair_energy(gi: tuple, gj: tuple) -> float:
    """:func:`pair_energy` of two branches' :func:`_geometry`."""
    ai0, ai1, ti0, ti1 = gi
    aj0, aj1, tj0, tj1 = gj
    cx, cy = aj0 - ai0, aj1 - ai1
    d = math.hypot(cx, cy)
    if d < 1e-9:
        phis = [_turn(ti0, ti1, -tj0, -tj1)]
        d = 1.0
    else:
        phis = [_turn(ti0, ti1, cx, cy), _turn(cx, cy, -tj0, -tj1)]
    return sum((2.0 * math.tan(phi / 2.0)) ** 2 for phi in phis) / d


def _perfect_matchings(items):
    if not items:
        yield []
        return
    first, rest = items[0], items[1:]
    for k in range(len(rest)):
        for m in _perfect_matchings(rest[:k] + rest[k + 1:]):
            yield [(first, rest[k])] + m


@lru_cache(maxsize=16)
def _all_matchings(n: int) -> tuple:
    """Every perfect matching of range(n) (odd n: of all but one, left out in turn), in enumeration order."""
    leave_out = [None] if n % 2 == 0 else list(range(n))
    return tuple(tuple(m) for skip in leave_out for m in _perfect_matchings([i for i in range(n) if i != skip]))


def colours_differ(ci, cj, min_separation: float) -> bool:
    return ci is not None and cj is not None and float(np.linalg.norm(ci - cj)) > min_separation


def paints_differ(ci, cj, min_separation: float, max_shade_hue_deg: float = SHADE_HUE_DEG,
                  min_shade_chroma: float = SHADE_CHROMA) -> bool:
    """:func:`colours_differ`, unless the two CIELAB (a*, b*) colours are one paint in light and shade:
    both chromatic (chroma above ``min_separation``), hues within ``max_shade_hue_deg``, the paler one with
    at least ``min_shade_chroma`` of the other's chroma. A shadow (of the rod above, next to a crossing)
    scales a rod's RGB by a factor, which scales a*b* about by its cube root, at the same hue: a factor down
    to 1/4 (half in a shadow on the rod's shaded side) keeps 0.6 of the chroma (a magenta rod: (43, -37)
    lit, (31, -27) in the shadow of its own loop, 16 apart); paler still is the table or a washed-out
    speck, not the rod."""
    if not colours_differ(ci, cj, min_separation):
        return False
    ri, rj = float(np.hypot(ci[0], ci[1])), float(np.hypot(cj[0], cj[1]))
    if min(ri, rj) <= max(min_separation, min_shade_chroma * max(ri, rj)):
        return True
    cos_hue = float(ci[0] * cj[0] + ci[1] * cj[1]) / (ri * rj)
    return cos_hue < math.cos(math.radians(max_shade_hue_deg))


def minimal_energy_pairing(branches: list, max_exhaustive: int = 8, colour_penalty: float = 4.0,
                           min_colour_separation: float = 12.0, loop_penalty: float = 0.5):
    """Pairs (i, j) of branch indices with the least total energy (bending plus colour penalty), and that
    energy. With an odd number of branches one is left unpaired."""
    n = len(branches)
    if n < 2:
        return [], 0.0
    energy = np.full((n, n), np.inf)
    geometry = [_geometry(b) for b in branches]
    for i, j in combinations(range(n), 2):
        e = _pair_energy(geometry[i], geometry[j])
        if paints_differ(branches[i].colour, branches[j].colour, min_colour_separation):
            e += colour_penalty
        if branches[i].edge == branches[j].edge:
            e += loop_penalty
        energy[i, j] = energy[j, i] = e
    if n <= max_exhaustive:
        best, best_e = [], np.inf
        table = energy.tolist()          # plain floats: the same sums, without numpy scalar indexing
        for m in _all_matchings(n):
            e = sum(table[i][j] for i, j in m)
            if e < best_e:
                best, best_e = m, e
        return list(best), float(best_e)
    # many branches (a tangle): greedy, cheapest pair first
    pairs, used, total = [], set(), 0.0
    for e, i, j in sorted((energy[i, j], i, j) for i, j in combinations(range(n), 2)):
        if i in used or j in used:
            continue
        pairs.append((i, j))
        used.update((i, j))
        total += e
    return pairs, float(total)


def pair_crossings(graph: SkeletonGraph, crossings: list, skip_px: float, fit_px: float, colour_of=None,
                   min_colour_separation: float = 12.0):
    """Attach branch geometry to every crossing and pair its branches by minimal bending energy."""
    attach_branch_geometry(graph, crossings, skip_px, fit_px, colour_of)
    for c in crossings:
        c.pairs, c.energy = minimal_energy_pairing(c.branches, min_colour_separation=min_colour_separation)
        if c.doubled_edge is not None:
            c.pairs = same_side_pairing(graph, c) or c.pairs
    return crossings


def same_side_pairing(graph: SkeletonGraph, crossing: Crossing):
    """The pairing at two crossings joined by a chain that carries both rods side by side (a lens, two rods
    crossing twice): the rod that enters on one side of the chain, seen along it, crosses to the other side
    at the first crossing and back at the second, so it leaves on the side it came in on. The branches'
    sides from their anchors against the chain's direction at each end (over its first and last quarter).
    The bending energy cannot tell: both pairings run straight through a long lens. [] where the two
    branches at one end are not on opposite sides."""
    e = graph.edges[crossing.doubled_edge]
    pts = e.points
    q = max(1, len(pts) // 4)
    side_of = {}
    for nid, direction in ((e.u, pts[q] - pts[0]), (e.v, pts[-1] - pts[-1 - q])):
        origin = graph.nodes[nid].position
        for k, b in enumerate(crossing.branches):
            if graph.edge_end_at(b.edge, b.side) == nid:
                r = b.anchor - origin
                side_of[k] = (nid, float(np.sign(direction[0] * r[1] - direction[1] * r[0])))
    pairs = []
    for k, (nid, side) in side_of.items():
        for m, (nid2, side2) in side_of.items():
            if k < m and nid != nid2 and side == side2 and side != 0:
                pairs.append((k, m))
    used = [k for p in pairs for k in p]
    return pairs if len(pairs) == 2 and len(set(used)) == 4 else []
