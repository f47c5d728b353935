"""Pattern and rod perception, image to ordered centrelines: the steps of mBEST (Choi et al. 2023) plus
sub-pixel refinement.

 1. segmentation (:mod:`.segmentation`): mask, foreground evidence, rough stroke width w (replaced by
    the mask's width on the skeleton's long chains when that is ``width_mismatch`` times larger: specks of
    a textured table bias the segmentation's 2 area / perimeter low); where segmentation finds no object
    because Otsu's split only separates a strongly textured table (a small rod), the evidence's upper class
    is split again (:func:`tail_threshold`);
 2. skeleton (Zhang-Suen thinning, :mod:`.thinning`; of the mask at half resolution when strokes are at
    least ``half_resolution_min_width_px`` wide) and its graph (:mod:`.skeleton_graph`); spurs shorter than
    ``spur_factor`` w + 2 px pruned, specks shorter than ``min_length_factor`` w dropped, and so are
    objects whose centreline evidence has a median below the segmentation threshold (texture blobs that
    only the local edge rule pulled into the mask), and so are loops from a junction back to itself no
    longer than a spur (pinholes in the mask) and dead-end branches inside a filled loop's blob
    (:func:`~.filled_loops.prune_blob_spurs`);
 3. crossings (:mod:`.bending_energy_pairing`): junctions closer than ``merge_factor`` w form one
    cluster, and clusters with an odd number of branches are joined to the nearest other odd one within
    ``y_merge_factor`` w along the skeleton (a shallow X split into two Ys, three rods crossing near one
    point), and, from their geometry, two Ys joined by a longer shared chain of about w / tan(angle / 2)
    (a shallow crossing) or by a chain as wide as both rods together (two rods side by side between two
    crossings, :func:`~.bending_energy_pairing.find_crossings`);
    branches paired by minimal bending energy (anchors ``skip_factor`` w + 2 px out, tangents over
    1.5 w), with a penalty for joining branches of clearly different colour (``min_colour_separation``;
    one hue at 0.6-1 times the chroma is one paint in light and shade, :func:`~.bending_energy_pairing.paints_differ`);
    across a chain of two rods side by side that narrows to one rod's width an even number of times (the
    rods cross at both Ys, or at neither) each branch is paired with the one on its side of the chain;
 4. traversal (:mod:`.traversal`): one ordered path per object, from an end (loops: closed paths); an
    object whose colour changes for good along its length is cut there (rods of different colours
    touching end to end, a rod end lying along another rod); then ends of different objects of one
    colour facing each other across at most ``max_gap_factor`` w are joined (a rod cut by the shadow of
    the rod above it, a pen skip), and across up to ``max_hidden_factor`` w if the stretch between them
    is covered by the mask but for at most ``max_gap_factor`` w (a rod hidden under another one along a
    length, a shallow crossing); w there is the wider object's own width (the mask's, median along it)
    where that is larger; objects no longer than 12 widths lying half on a longer one are dropped (a strand of
    texture specks along a rod, :func:`~.slivers.drop_riding_strands`);
 5. over/under at every crossing from colour where the strands differ, else from the occlusion edges
    (the upper strand's boundary runs on through the overlap), with a confidence (:mod:`.crossing_order`);
 6. centreline (:mod:`.centreline`): edge-centred refinement (profiles across each path as wide as its
    object's own width, the mask's median along it, where that is larger than w; where the rod's colour
    stands out from the table's, the edges of the rod's share of the light,
    :func:`~.centreline.rod_share_profiles`, which neither a rod's dark flank nor its shadow moves),
    Gaussian smoothing (``smoothing_sigma_px``),
    ends one half-width inside the boundary (ends at a branch left unpaired at a crossing, a rod end against
    or on another rod: placed by colour, :func:`~.traversal.place_abutting_end`), a small self loop whose
    hole the mask closes re-traced round its blob (:func:`~.filled_loops.trace_filled_loop`); where two
    paths run together down one strip of the mask as wide as both rods (rods lying side by side along a
    stretch), each moved onto its own rod, against the strip's edge on its side
    (:func:`~.side_by_side.separate_side_by_side`); arc-length resampling every ``step_px``.

Objects are numbered by decreasing length. An open path starts at its end with the smaller column
(leftmost; then the upper one), a closed path at its leftmost point, running counter-clockwise as seen in
the image. Images above ``max_pixels`` are processed at a reduced scale (INTER_AREA) and the results are
mapped back to full-resolution pixels. Units: pixels, points (row, col), integer values at pixel centres.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from numba import njit

from rod_deploy.perception import centreline as cl
from rod_deploy.perception.bending_energy_pairing import find_crossings, pair_crossings
from rod_deploy.perception.crossing_order import colour_sampler, decide_crossings
from rod_deploy.perception.filled_loops import prune_blob_spurs, trace_filled_loop
from rod_deploy.perception.segmentation import (Segmentation, SegmentationConfig, SegmentationError, _otsu, as_bgr,
                                                estimate_background, foreground_evidence, segment)
from rod_deploy.perception.side_by_side import separate_side_by_side
from rod_deploy.perception.slivers import drop_riding_strands
from rod_deploy.perception.skeleton_graph import (build_skeleton_graph, dissolve_pass_through_junctions,
                                                  prune_spurs, remove_small_parts, skeleton_of)
from rod_deploy.perception.traversal import (drop_shadow_strands, join_gaps, place_abutting_end,
                                             split_at_colour_changes, trace_objects, unpaired_branch_ends)


class PerceptionError(ValueError):
    """No usable stroke or rod in the image (the message says why)."""


@dataclass(frozen=True)
class PerceptionConfig:
    segmentation: SegmentationConfig = SegmentationConfig()
    step_px: float = 1.0                 # output point spacing along each path
    smoothing_sigma_px: float = 1.5      # Gaussian smoothing along the path
    spur_factor: float = 1.2             # spurs shorter than spur_factor * w + 2 px are pruned
    min_length_factor: float = 4.0       # objects shorter than this many widths are dropped
    merge_factor: float = 0.75           # junctions joined by chains shorter than this * w: one crossing
    y_merge_factor: float = 8.0          # odd junction clusters joined along chains shorter than this * w
    skip_factor: float = 0.5             # branch anchors this many widths (+ 2 px) out of the crossing
    max_gap_factor: float = 3.0          # facing ends at most this many widths apart are joined (0: never)
    max_hidden_factor: float = 20.0      # ... up to this many if hidden under other rods (0: never)
    refine: bool = True                  # edge-centred sub-pixel refinement
    min_colour_separation: float = 12.0  # CIELAB a*b* difference needed to decide over/under
    max_pixels: int = 12_000_000         # larger images are processed downscaled
    half_resolution_min_width_px: float = 9.0   # skeleton at half resolution for strokes this wide
    width_mismatch: float = 1.3          # the skeleton's width replaces w when this many times larger

    def __post_init__(self):
        if not self.step_px > 0:
            raise ValueError(f'step_px must be > 0, got {self.step_px}')
        if self.smoothing_sigma_px < 0:
            raise ValueError(f'smoothing_sigma_px must be >= 0, got {self.smoothing_sigma_px}')
        if self.max_pixels < 10_000:
            raise ValueError(f'max_pixels must be >= 10000, got {self.max_pixels}')


@dataclass
class PerceivedObject:
    points: np.ndarray       # (n, 2) (row, col) [px], ordered from one end (closed: first point repeated)
    width_px: float          # stroke / rod width
    closed: bool

    def length_px(self) -> float:
        return float(cl.arc_length(self.points)[-1]) if len(self.points) > 1 else 0.0


@dataclass
class PerceptionResult:
    objects: list
    crossings: list                          # CrossingDecision, positions in full-resolution pixels
    segmentation: Segmentation               # at processing scale
    image_shape: tuple
    scale: float = 1.0                       # processing pixels per image pixel
    timings_ms: dict = field(default_factory=dict)

    def summary(self) -> str:
        colour = sum(1 for c in self.crossings if c.over is not None and c.cue == 'colour')
        edges = sum(1 for c in self.crossings if c.over is not None and c.cue == 'edges')
        return (f'{len(self.objects)} object(s), lengths '
                f'{", ".join(f"{o.length_px():.0f}" for o in self.objects)} px, widths '
                f'{", ".join(f"{o.width_px:.1f}" for o in self.objects)} px; {len(self.crossings)} crossing(s), '
                f'over/under decided from colour at {colour}, from occlusion edges at {edges}; segmentation '
                f'{self.segmentation.describe()}')


def perceive(image: np.ndarray, config: PerceptionConfig = PerceptionConfig()) -> PerceptionResult:
    """Ordered centrelines of the strokes or rods in ``image`` (BGR, BGRA or grey uint8)."""
    timings = {}
    t0 = time.perf_counter()
    try:
        bgr = as_bgr(image)
    except SegmentationError as exc:
        raise PerceptionError(str(exc)) from None
    shape = bgr.shape[:2]
    scale = 1.0
    if shape[0] * shape[1] > config.max_pixels:
        scale = float(np.sqrt(config.max_pixels / (shape[0] * shape[1])))
        size = (max(1, int(round(shape[1] * scale))), max(1, int(round(shape[0] * scale))))
        bgr = cv2.resize(bgr, size, interpolation=cv2.INTER_AREA)
    try:
        seg = segment(bgr, config.segmentation)
    except SegmentationError as exc:
        t_tail = tail_threshold(bgr, config.segmentation)
        if t_tail is None:
            raise PerceptionError(str(exc)) from None
        try:
            seg = segment(bgr, replace(config.segmentation, threshold=t_tail))
        except SegmentationError:
            raise PerceptionError(str(exc)) from None
    w = seg.stroke_width_px
    t1 = time.perf_counter()
    timings['segmentation'] = (t1 - t0) * 1e3

    mask, f = skeleton_mask(seg, config)
    graph = build_skeleton_graph(skeleton_of(mask))
    skel_dist = distance_map(mask)
    w = _centreline_width(graph, skel_dist, f, w, config.width_mismatch)
    ws = w / f
    t2 = time.perf_counter()
    timings['skeleton'] = (t2 - t1) * 1e3

    def to_full(p):                          # processing-scale skeleton pixels -> image pixels
        return f * np.asarray(p) + 0.5 * (f - 1)

    colour_full = colour_sampler(bgr)

    def colour_of(points):
        return colour_full(to_full(points))

    colour_of.batch = lambda point_sets: colour_full.batch([to_full(p) for p in point_sets])

    min_length = max(config.min_length_factor * w, 8.0)
    remove_small_parts(graph, min_length / f)
    prune_spurs(graph, config.spur_factor * ws + 2.0)
    prune_blob_spurs(graph, skel_dist, ws, config.spur_factor * ws + 2.0)
    dissolve_pass_through_junctions(graph)
    remove_small_parts(graph, min_length / f)
    crossings = find_crossings(graph, config.merge_factor * ws, config.y_merge_factor * ws,
                               width_at=lambda p: 2.0 * cl.lookup(skel_dist, p),
                               fit_px=1.5 * ws + 2.0)
    pair_crossings(graph, crossings, config.skip_factor * ws + 2.0, 1.5 * ws + 2.0, colour_of,
                   config.min_colour_separation)
    traced = trace_objects(graph, crossings)
    for o in traced:
        o.points = to_full(o.points)
    tees = unpaired_branch_ends(crossings, to_full, f)
    traced = split_at_colour_changes(traced, colour_full.at, w, config.min_colour_separation, min_length)
    traced, gaps = join_gaps(traced, w, len(crossings), config.max_gap_factor, colour_of=colour_full,
                             min_colour_separation=config.min_colour_separation,
                             covered=lambda p: cl.lookup(seg.mask, p), max_hidden_factor=config.max_hidden_factor,
                             width_of=lambda p: f * (2.0 * _median_evidence(skel_dist, (p - 0.5 * (f - 1)) / f)
                                                     - 1.0))
    zones = [(to_full(c), f * r) for c, r in _crossing_zones(crossings, ws)]
    zones += [(g.centre, 0.5 * g.length_px + 0.5 * w) for g in gaps]
    zone_centres = np.array([c for c, _ in zones], dtype=np.float64).reshape(-1, 2)
    zone_radii = np.array([r for _, r in zones], dtype=np.float64)
    traced = [o for o in traced if o.length_px() >= min_length]
    if not traced:
        raise PerceptionError(f'no stroke or rod found: every candidate is shorter than {min_length:.0f} px')
    traced = [o for o in traced if _median_evidence(seg.evidence, o.points) >= seg.threshold]
    if not traced:
        raise PerceptionError('no stroke or rod found: no candidate is clearly brighter or darker than the '
                              'background along its length (texture?)')
    dist = [skel_dist if f == 1 else None]

    def half_width_at(p):      # the mask's distance map at full resolution (the skeleton's when f == 1), lazily
        if dist[0] is None:
            dist[0] = distance_map(seg.mask)
        return cl.lookup(dist[0], p)

    if len(traced) > 1:
        traced = drop_shadow_strands(traced, colour_full.lab_at, half_width_at, config.min_colour_separation)
        traced = drop_riding_strands(traced, half_width_at)
    t3 = time.perf_counter()
    timings['graph'] = (t3 - t2) * 1e3

    decisions = decide_crossings(bgr, traced, w, config.min_colour_separation,
                                 width_at=lambda p: 2.0 * half_width_at(p) - 1.0)
    t4 = time.perf_counter()
    timings['crossing_order'] = (t4 - t3) * 1e3

    evidence = seg.evidence                # uint8: sampled bilinearly as float32 (no float copy)
    floor = 0.25 * seg.threshold
    paths, widths = [], []
    for obj in traced:
        if config.refine:
            w_obj = max(w, 2.0 * float(cl._median(half_width_at(obj.points))) - 1.0)   # a rod wider than w
            refined = cl.refine(obj.points, obj.closed, evidence, w_obj, floor,
                                exclude=lambda p: _in_zones(p, zone_centres, zone_radii),
                                sigma_px=config.smoothing_sigma_px, colour=(bgr, seg.background))
            width = refined.width_px if np.isfinite(refined.width_px) else w
            refined = cl.place_ends(refined, evidence, floor, 0.5 * width, tangent_px=max(4.0, w))
            refined.points = _place_abutting_ends(obj, refined.points, tees, colour_full.at, half_width_at, w, f,
                                                  config.min_colour_separation)
            if not obj.closed:
                half_width_at(obj.points[:1])                  # the full-resolution distance map, once
                refined.points = trace_filled_loop(refined.points, dist[0],
                                                   [o.points for o in traced if o is not obj],
                                                   [obj.points[i0:i1 + 1] for _, i0, i1 in obj.passes])
        else:
            pts = cl.smooth(cl.resample(obj.points, 1.0), config.smoothing_sigma_px, obj.closed)
            width = w
            refined = cl.RefinedPath(pts, w, obj.closed, np.full(len(pts), np.nan))
        paths.append(refined.points)
        widths.append(width)
    if config.refine and len(paths) > 1:
        paths = separate_side_by_side(paths, widths, [o.closed for o in traced], seg.mask, colour_full.at,
                                      [(d.objects[0], d.objects[1], d.position) for d in decisions
                                       if d.objects[0] != d.objects[1]], config.min_colour_separation)
    objects = [PerceivedObject(cl.resample(p, config.step_px * scale) / scale, width / scale, obj.closed)
               for p, width, obj in zip(paths, widths, traced)]
    t5 = time.perf_counter()
    timings['centreline'] = (t5 - t4) * 1e3

    objects, decisions = _canonical_order(objects, decisions)
    for d in decisions:
        d.position = d.position / scale
    timings['total'] = (time.perf_counter() - t0) * 1e3
    return PerceptionResult(objects, decisions, seg, tuple(shape), scale, timings)


def tail_threshold(bgr: np.ndarray, config: SegmentationConfig = SegmentationConfig(), max_levels: int = 3):
    """An evidence threshold for a small rod on a strongly textured table, or None. When the rods cover a
    tiny part of the image, Otsu's split of the evidence separates the table's texture from the rest (the
    two classes then differ by less than ``min_contrast`` and segmentation finds nothing); the rods are in
    the upper class's tail. So the upper class is split again by Otsu, up to ``max_levels`` times, and the
    first split whose two parts (above it; between it and the previous split) differ by at least
    ``min_contrast`` grey levels is the threshold. A texture's tail thins out smoothly (its splits differ
    by ~10 grey levels on the textured tables of the crossing scenes, 35-59 where a rod is there)."""
    if config.threshold is not None:
        return None
    s = foreground_evidence(bgr, estimate_background(bgr, config.background_block_px), config.method)
    sub = np.ascontiguousarray(s[::2, ::2]) if min(s.shape) >= 64 else s
    hist = cv2.calcHist([sub], [0], None, [256], [0, 256]).ravel().astype(np.float64)
    levels = np.arange(256)
    t = -1.0
    for _ in range(max_levels + 1):
        part = hist.copy()
        part[:int(t) + 1] = 0.0
        if part.sum() == 0:
            return None
        t_prev, t = t, _otsu(part)
        upper, lower = part * (levels > t), part * (levels <= t)
        if upper.sum() == 0 or lower.sum() == 0:
            return None
        gap = (upper * levels).sum() / upper.sum() - (lower * levels).sum() / lower.sum()
        if t_prev >= 0 and gap >= config.min_contrast:
            return float(t)
    return None


def skeleton_mask(seg: Segmentation, config: PerceptionConfig = PerceptionConfig()):
    """(mask to thin, f): the segmentation mask, or for wide strokes (``half_resolution_min_width_px``) the
    mask at half resolution, f = 2 (4x fewer pixels to thin and walk; the centreline is refined on the
    full-resolution evidence afterwards)."""
    if seg.stroke_width_px < config.half_resolution_min_width_px:
        return seg.mask, 1
    h2, w2 = seg.mask.shape[0] // 2, seg.mask.shape[1] // 2
    half = cv2.resize(seg.mask[:2 * h2, :2 * w2].view(np.uint8) * np.uint8(255), (w2, h2),
                      interpolation=cv2.INTER_AREA) >= 128
    return half, 2


def distance_map(mask: np.ndarray) -> np.ndarray:
    """``cv2.distanceTransform(mask, DIST_L2, 3)`` of a bool mask, computed on the rows of its bounding box
    and one background row either side (or the image border): every chamfer path from inside to the
    background outside crosses such a row, so the values are the same, bit for bit (checked on random masks
    in the tests; a crop of the columns is not: OpenCV's vectorised passes round differently there). OpenCV
    writes straight into those rows of the output, and only the rows outside them are zeroed (no full-size
    temporary, copy or zero fill)."""
    _, r, w, h = cv2.boundingRect(mask.view(np.uint8))
    if w == 0 or h == 0:
        return np.zeros(mask.shape, np.float32)
    r0, r1 = max(r - 1, 0), min(r + h + 1, mask.shape[0])
    out = np.empty(mask.shape, np.float32)
    out[:r0] = 0.0
    out[r1:] = 0.0
    cv2.distanceTransform(mask[r0:r1].view(np.uint8), cv2.DIST_L2, 3, dst=out[r0:r1])
    return out


def _centreline_width(graph, dist, f, w, mismatch):
    """The stroke width: the segmentation's 2 area / perimeter ``w``, unless the skeleton's chains longer
    than 6 w, pooled, sit in a mask more than ``mismatch`` times wider (median of 2 d - 1 on them, d the distance to the
    background, at processing scale ``f``): specks of a textured table left in the mask bias 2 A / P low."""
    points = [e.points for _, e in graph.live_edges() if e.length_px() >= 6.0 * w / f]   # not specks
    if not points:
        return w
    w_centre = f * (2.0 * float(cl._median(cl.lookup(dist, np.vstack(points)))) - 1.0)
    return w_centre if w_centre > mismatch * w else w


def _median_evidence(evidence, points):
    """``np.median`` of the (uint8) evidence at ``points``: the middle value, or the mean of the two middle
    ones in float64, without np.median's per-call overhead."""
    v = np.sort(cl.lookup(evidence, points))
    if not len(v):
        return float('nan')
    h = len(v) // 2
    return float(v[h]) if len(v) % 2 else (float(v[h - 1]) + float(v[h])) / 2


def _crossing_zones(crossings, w):
    zones = []
    for c in crossings:
        if not c.branches:
            continue
        radius = max(float(np.linalg.norm(b.anchor - c.centre)) for b in c.branches) + 0.5 * w
        zones.append((c.centre, radius))
    return zones


def _in_zones(points, centres, radii):
    """True for the (row, col) ``points`` within ``radii`` of any of the (k, 2) ``centres`` (np.hypot, compiled)."""
    out = np.zeros(len(points), dtype=np.bool_)
    _in_discs(np.ascontiguousarray(points, dtype=np.float64), centres, radii, out)
    return out


@njit(cache=True, nogil=True)
def _in_discs(points, centres, radii, out):
    for i in range(points.shape[0]):
        for z in range(radii.size):
            if np.hypot(points[i, 0] - centres[z, 0], points[i, 1] - centres[z, 1]) <= radii[z]:
                out[i] = True
                break


def _canonical_order(objects, decisions):
    """Objects by decreasing length; open paths from the leftmost end, closed ones counter-clockwise
    (as seen in the image) from their leftmost point. Crossing decisions are renumbered to match."""
    for obj in objects:
        p = obj.points
        if obj.closed:
            body = p[:-1]
            x, y = body[:, 1], -body[:, 0]
            area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
            if area < 0:
                body = body[::-1]
            k = int(np.lexsort((body[:, 0], body[:, 1]))[0])
            body = np.roll(body, -k, axis=0)
            obj.points = np.vstack([body, body[:1]])
        elif (p[-1, 1], p[-1, 0]) < (p[0, 1], p[0, 0]):
            obj.points = p[::-1].copy()
    order = sorted(range(len(objects)), key=lambda i: -objects[i].length_px())
    new_id = {old: new for new, old in enumerate(order)}
    for d in decisions:
        d.objects = tuple(new_id[o] for o in d.objects)
        d.over = None if d.over is None else new_id[d.over]
        d.spans = ()
    return [objects[i] for i in order], decisions


def _place_abutting_ends(obj, points, tees, colours_at, half_width_at, w, f, min_colour_separation):
    """Ends of ``obj`` that start at an unpaired crossing branch (a rod's end against or on another
    rod), placed by colour (:func:`~.traversal.place_abutting_end`); the rod's own width from the mask's
    distance map along it (median of 2 d - 1)."""
    if obj.closed or not tees:
        return points
    width = None
    for end in (0, 1):
        traced_end = obj.points[-1 if end else 0]
        for anchor, centre, other_width in tees:
            if np.hypot(*(traced_end - anchor)) <= f:
                if width is None:
                    width = max(2.0 * float(cl._median(half_width_at(points))) - 1.0, 1.0)
                p = points if end else points[::-1]
                p = place_abutting_end(p, anchor, centre, colours_at, width, max(other_width, w),
                                       min_colour_separation)
                points = p if end else p[::-1]
                break
    return points
