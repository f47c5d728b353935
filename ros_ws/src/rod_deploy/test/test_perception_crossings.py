"""Crossings and loops: the synthetic crossing scenes, over/under from occlusion edges, shadow strands,
and ordered paths through self crossings, a rod under a loop and two rods crossing twice."""
import numpy as np
import pytest

from rod_deploy.perception.crossing_order import occlusion_edge_strength
from rod_deploy.perception.crossing_scenes import (TrueCrossing, crossing_scene, curve_crossings, knot_curve,
                                                   render_rod_scene)
from rod_deploy.perception.evaluation import arc_length_error, centreline_rms
from rod_deploy.perception.centreline import arc_length
from rod_deploy.perception.path_io import deployed_order
from rod_deploy.perception.pipeline import perceive
from rod_deploy.perception.traversal import TracedObject, drop_shadow_strands, join_gaps


def test_curve_crossings_finds_exact_crossings():
    a = np.stack([np.full(101, 50.0), np.linspace(0, 100, 101)], axis=1)          # row 50
    b = np.stack([np.linspace(0, 100, 101), np.linspace(0, 100, 101)], axis=1)    # diagonal
    (c,) = curve_crossings([a, b])
    assert c.rods == (0, 1) and np.allclose(c.position, [50, 50], atol=1e-6)
    assert np.isclose(c.angle_rad, np.pi / 4, atol=1e-3)
    assert np.allclose(c.s_px, [50, 50 * np.sqrt(2)], atol=1e-3)
    assert len(curve_crossings([knot_curve(300)])) == 3          # an overhand knot crosses itself 3 times


def test_rendered_crossing_shows_the_upper_rod():
    a = np.stack([np.full(200, 100.0), np.linspace(10, 190, 200)], axis=1)
    b = np.stack([np.linspace(10, 190, 200), np.full(200, 100.0)], axis=1)
    for over, colour in ((0, (0, 0, 220)), (1, (0, 220, 0))):
        cs = curve_crossings([a, b])
        cs[0].over = over
        img = render_rod_scene((200, 200), [a, b], [10, 10], [(0, 0, 220), (0, 220, 0)], cs, noise_std=0,
                               blur_sigma=0, texture=0, shadow_strength=0.5)
        px = img[100, 100].astype(int)
        assert np.argmax(px) == np.argmax(colour)


def _read_in_order(curves, image):
    res = perceive(image)
    assert len(res.objects) == len(curves)
    for curve in curves:
        best = min(res.objects, key=lambda o: centreline_rms(o.points, curve)['rms_px'])
        assert centreline_rms(best.points, curve)['rms_px'] <= 1.0
        assert arc_length_error(best.points, curve)['mean_px'] <= 2.0
    return res


@pytest.mark.parametrize('kind', ['letter_e', 'knot', 'self_loop'])
def test_self_crossing_rod_is_read_in_order(kind):
    """One scene of each self-crossing kind (a seed outside both benchmark sets): one rod, within 1 px
    RMS and 2 px ordered Eq. 17."""
    sc = crossing_scene(kind, 31)
    _read_in_order(sc.curves, sc.image)


def test_rod_under_a_loop_of_another_rod_of_the_same_colour():
    """Rod b crosses rod a three times, twice under a's loop, both rods of (nearly) one colour: the
    order through all crossings and over/under from the occlusion edges. (A regression case: the same
    loop crossed at other angles is not always read right yet, see the README.)"""
    from rod_deploy.perception.crossing_scenes import loop_curve
    a = loop_curve(np.random.default_rng(3), 80.0, t_in=2.4, t_out=2.4)
    a = a - a.mean(axis=0) + [240, 320]
    (own,) = curve_crossings([a])
    s = np.arange(len(a))                                   # loop_curve is sampled every 1 px
    centre = a[(s > own.s_px[0]) & (s < own.s_px[1])].mean(axis=0)
    t = np.linspace(-400, 400, 801)
    b = centre + t[:, None] * np.array([np.sin(np.pi / 3), np.cos(np.pi / 3)])
    b = b[(b[:, 0] > 15) & (b[:, 0] < 465) & (b[:, 1] > 15) & (b[:, 1] < 625)]
    cs = curve_crossings([a, b])
    assert sum(c.rods == (0, 1) for c in cs) == 3
    for c in cs:
        c.over = 0
    img = render_rod_scene((480, 640), [a, b], [10, 9], [(60, 220, 200), (70, 210, 190)], cs, seed=5)
    res = _read_in_order([a, b], img)
    decided = [c for c in res.crossings if c.objects[0] != c.objects[1] and c.over is not None]
    assert len(decided) >= 2
    assert all(centreline_rms(res.objects[c.over].points, a)['rms_px'] < 1.0 for c in decided)


def test_same_colour_crossing_decided_from_occlusion_edges():
    """Two rods of one colour: colour cannot decide, the upper rod's continuous boundary does."""
    a = np.stack([np.full(300, 150.0), np.linspace(20, 280, 300)], axis=1)
    b = np.stack([np.linspace(20, 280, 300), 40 + 0.8 * np.linspace(20, 280, 300)], axis=1)
    for over in (0, 1):
        cs = curve_crossings([a, b])
        cs[0].over = over
        img = render_rod_scene((300, 300), [a, b], [12, 12], [(60, 220, 200)] * 2, cs, seed=over)
        res = perceive(img)
        assert len(res.objects) == 2
        (dec,) = [c for c in res.crossings if c.objects[0] != c.objects[1]]
        assert dec.cue == 'edges' and dec.confidence >= 0.05
        truth = a if over == 0 else b
        upper = res.objects[dec.over]
        assert centreline_rms(upper.points, truth)['rms_px'] < 1.0


def test_occlusion_edge_strength_is_nan_for_shallow_crossings():
    grey = np.zeros((50, 50), np.float32)
    assert np.isnan(occlusion_edge_strength(grey, (25, 25), np.array([0.0, 1.0]), np.array([0.1, 0.995]), 6))


def test_shadow_strand_beside_a_rod_is_dropped_but_a_rod_alongside_is_kept():
    rod = TracedObject(np.stack([np.full(200, 50.0), np.arange(200.0)], axis=1))
    shadow = TracedObject(np.stack([np.full(40, 58.0), np.arange(80.0, 120.0)], axis=1))
    neighbour = TracedObject(np.stack([np.full(150, 62.0), np.arange(20.0, 170.0)], axis=1))
    sliver = TracedObject(np.stack([np.full(60, 52.0), np.arange(60.0, 120.0)], axis=1))

    def lab_at(points):         # the rod and its neighbour: bright red; the shadow: dark grey
        out = np.tile([60.0, 50.0, 30.0], (len(points), 1))
        out[np.isclose(points[:, 0], 58.0)] = [25.0, 0.0, 0.0]
        return out

    half_width = lambda p: np.full(len(p), 5.0)            # noqa: E731  rods 10 px wide
    kept = drop_shadow_strands([rod, shadow, neighbour, sliver], lab_at, half_width, 12.0)
    assert kept == [rod, neighbour]


def test_wide_rod_cut_at_a_shallow_crossing_is_joined_with_its_own_width():
    """A 12 px rod cut by a thinner rod above it at a shallow angle (its gap 50 px, 25 px of it not in the
    mask: the upper rod's shadow) in an image whose typical width w is 7 px: joined when the ends are
    measured with the rod's own width, not with w alone; never across an uncovered stretch longer than
    3 of its widths."""
    def piece(c0, c1):
        return TracedObject(np.stack([np.full(c1 - c0 + 1, 100.0), np.arange(c0, c1 + 1.0)], axis=1))

    def covered_except(lo, hi):
        return lambda p: ~((p[:, 1] > lo) & (p[:, 1] < hi))

    colour = lambda p: np.array([30.0, 40.0])                          # noqa: E731  one colour
    own_width = lambda p: 12.0                                           # noqa: E731
    args = dict(colour_of=colour, min_colour_separation=12.0, max_hidden_factor=20.0)
    joined, gaps = join_gaps([piece(0, 150), piece(200, 350)], 7.0, 0, covered=covered_except(160, 186),
                             width_of=own_width, **args)
    assert len(joined) == 1 and len(gaps) == 1
    assert joined[0].points[0, 1] == 0 and joined[0].points[-1, 1] == 350
    kept, _ = join_gaps([piece(0, 150), piece(200, 350)], 7.0, 0, covered=covered_except(160, 186), **args)
    assert len(kept) == 2                                               # with w = 7 px only: too far
    kept, _ = join_gaps([piece(0, 150), piece(200, 350)], 7.0, 0, covered=covered_except(150, 200),
                        width_of=own_width, **args)
    assert len(kept) == 2                                               # 49 px uncovered > 3 x 12 px


def test_shallow_crossing_scene_lower_rod_read_as_one():
    """A generated shallow scene (development seed 6400004: a teal rod 7.9 px wide over an orange one
    11.4 px wide at 26 degrees on a textured table, where the typical width w comes out 7 px): the lower
    rod, cut in the mask by the upper one and its shadow, is one object again (it came back in two pieces,
    3 objects for 2 rods, 75 px RMS). Its centreline is still 1.3 px RMS off (the 1 px bar is missed
    through the crossing), so the bound here is 1.5 px."""
    sc = crossing_scene('shallow', 6_400_004)
    res = perceive(sc.image)
    assert len(res.objects) == 2
    for curve in sc.curves:
        best = min(res.objects, key=lambda o: centreline_rms(o.points, curve)['rms_px'])
        assert centreline_rms(best.points, curve)['rms_px'] <= 1.5
        assert arc_length_error(best.points, curve)['mean_px'] <= 2.0


def test_deployed_order_starts_at_the_named_end():
    p = np.stack([np.linspace(0, 1, 11), np.zeros(11)], axis=1)
    assert np.allclose(deployed_order(p, False, (0.9, 0.1))[0], [1, 0])
    assert np.allclose(deployed_order(p, False, None), p)
    ring = np.vstack([np.stack([np.cos(t), np.sin(t)], axis=1) for t in [np.linspace(0, 2 * np.pi, 9)[:-1]]])
    closed = np.vstack([ring, ring[:1]])
    out = deployed_order(closed, True, (0.0, -1.1))
    assert np.allclose(out[0], [0, -1], atol=1e-9) and np.allclose(out[0], out[-1]) and len(out) == 9


def _shallow_x(angle_deg, widths=(11.0, 8.0), colours=((60, 60, 200), (70, 70, 210)), texture=0.0):
    """Two straight rods crossing at ``angle_deg`` in the middle of a 300 x 400 image (a near copy of
    one colour: colour cannot pair the branches)."""
    t = np.linspace(-170, 170, 341)[:, None]
    half = np.radians(angle_deg) / 2
    centre = np.array([150.0, 200.0])
    curves = [centre + t * np.array([np.sin(s * half), np.cos(s * half)]) for s in (1, -1)]
    cs = curve_crossings(curves)
    img = render_rod_scene((300, 400), curves, list(widths), list(colours), cs, texture=texture, seed=1)
    return curves, img


@pytest.mark.parametrize('angle_deg', [14.0])
def test_shallow_crossing_is_one_crossing_of_two_ys(angle_deg):
    """A shallow X leaves two Y junctions joined by a shared chain about w / tan(angle / 2) long (longer
    than the 8 w of the odd-cluster rule at these angles): they form one crossing of four branches,
    paired straight through, and both rods come back whole within 1 px."""
    from rod_deploy.perception import bending_energy_pairing as bep
    found = []
    original = bep.find_crossings

    def spy(*args, **kwargs):
        found.extend(original(*args, **kwargs))
        return found
    curves, img = _shallow_x(angle_deg)
    import rod_deploy.perception.pipeline as pipeline
    pipeline_find, pipeline.find_crossings = pipeline.find_crossings, spy
    try:
        res = _read_in_order(curves, img)
    finally:
        pipeline.find_crossings = pipeline_find
    shallow = [c for c in found if c.overlap_px > 0]
    assert len(shallow) == 1 and len(shallow[0].branches) == 4
    w = np.mean([o.width_px for o in res.objects])
    expected = w / np.tan(np.radians(angle_deg) / 2)
    assert 0.5 * expected <= shallow[0].overlap_px <= 1.5 * expected


def test_an_eye_is_not_a_shallow_crossing():
    """Two strands that part and meet again (a rod and the shadow beside it, two rods lying side by side)
    leave two Ys joined by two chains: no shallow crossing."""
    import cv2
    from rod_deploy.perception.bending_energy_pairing import find_crossings
    from rod_deploy.perception.skeleton_graph import build_skeleton_graph, skeleton_of
    mask = np.zeros((200, 400), np.uint8)
    cv2.line(mask, (20, 100), (380, 100), 1, 9)
    cv2.ellipse(mask, (200, 100), (90, 14), 0, 180, 360, 1, 7)        # a strand leaving and rejoining the rod
    graph = build_skeleton_graph(skeleton_of(mask.astype(bool)))
    dist = cv2.distanceTransform(mask, cv2.DIST_L2, 3)
    crossings = find_crossings(graph, 6.0, 64.0, width_at=lambda p: 2.0 * dist[tuple(np.round(p).astype(int).T)],
                               fit_px=15.0)
    assert not any(c.overlap_px > 0 for c in crossings)


def test_stroke_width_from_the_skeleton_when_texture_specks_bias_the_segmentation():
    """Specks of a textured table left in the mask pull the segmentation's 2 area / perimeter far below
    the rod's width; the width on the skeleton's long chains replaces it."""
    import cv2
    from rod_deploy.perception.pipeline import _centreline_width
    from rod_deploy.perception.skeleton_graph import build_skeleton_graph, skeleton_of
    mask = np.zeros((300, 400), np.uint8)
    cv2.line(mask, (30, 150), (370, 150), 1, 11)
    rng = np.random.default_rng(0)
    for r, c in rng.integers(10, 290, (150, 2)):
        if abs(r - 150) > 15:
            cv2.circle(mask, (int(c), int(r)), 2, 1, -1)
    dist = cv2.distanceTransform(mask, cv2.DIST_L2, 3)
    graph = build_skeleton_graph(skeleton_of(mask.astype(bool)))
    n = int(mask.sum())
    perimeter = n - int(cv2.erode(mask, np.ones((3, 3), np.uint8)).sum())
    w_seg = 2.0 * n / perimeter
    assert w_seg < 7.0
    assert abs(_centreline_width(graph, dist, 1, w_seg, 1.3) - 11.0) <= 1.5
    assert _centreline_width(graph, dist, 1, 10.5, 1.3) == 10.5          # a fair estimate stays


def test_overlay_marks_undecided_crossings():
    """An undecided crossing gets a white '?' beside it, a decided one does not (it gets a ring)."""
    from rod_deploy.perception.crossing_order import CrossingDecision
    from rod_deploy.perception.overlay import draw_overlay
    from rod_deploy.perception.pipeline import PerceivedObject
    t = np.linspace(220, 380, 161)          # crossing at (300, 300), far from the legend (top left)
    objects = [PerceivedObject(np.stack([t, t], axis=1), 8.0, False),
               PerceivedObject(np.stack([t, 600 - t], axis=1), 8.0, False)]
    img = np.full((400, 400, 3), 80, np.uint8)
    label = (slice(300 - 20, 300 - 4), slice(300 + 4, 300 + 16))       # where the '?' goes (up, right)

    def white_in_label(over):
        d = CrossingDecision(0, np.array([300.0, 300.0]), (0, 1), over, 0.0 if over is None else 1.0, 40.0,
                             cue=None if over is None else 'colour')
        ov = draw_overlay(img, objects, [d])
        return int(np.all(ov[label] >= 250, axis=2).sum())
    assert white_in_label(None) >= 10 and white_in_label(0) == 0


def _thin_on_thick(over, angle_deg=60.0, widths=(7.0, 14.0), seed=2):
    """A thin and a thick rod of (nearly) one colour crossing at ``angle_deg``; ``over`` the upper rod's
    index (0: the thin one)."""
    t = np.linspace(-180, 180, 361)[:, None]
    a = np.array([200.0, 260.0]) + t * np.array([np.sin(np.radians(angle_deg)), np.cos(np.radians(angle_deg))])
    b = np.array([200.0, 260.0]) + t * np.array([0.0, 1.0])
    keep = lambda c: c[(c[:, 0] > 10) & (c[:, 0] < 390) & (c[:, 1] > 10) & (c[:, 1] < 510)]   # noqa: E731
    curves = [keep(a), keep(b)]
    cs = curve_crossings(curves)
    cs[0].over = over
    img = render_rod_scene((400, 520), curves, list(widths), [(60, 220, 200), (66, 226, 204)], cs,
                           background=(120, 110, 130), texture=6.0, seed=seed)
    return curves, img


@pytest.mark.parametrize('over', [0, 1])
def test_thin_rod_on_a_thick_one_is_never_ordered_wrong(over):
    """Rods of one colour, 7 and 14 px wide, crossing at 45 degrees: over/under from the occlusion edges
    must be right or undecided, never wrong (each strand's own width, the footprint window along the
    other strand, the worst case over the direction tolerance; the rules before them put the thick rod on
    top of the thin one here)."""
    curves, img = _thin_on_thick(over, angle_deg=45.0, seed=3)
    res = perceive(img)
    assert len(res.objects) == 2
    (dec,) = [c for c in res.crossings if c.objects[0] != c.objects[1]]
    if dec.over is not None:
        truth = curves[over]
        assert centreline_rms(res.objects[dec.over].points, truth)['rms_px'] < 1.0


def test_over_under_from_edges_is_right_at_a_thin_rod_over_a_thick_one():
    """At 75 degrees, with the thin rod on top, the order is decided, and right."""
    curves, img = _thin_on_thick(0, angle_deg=75.0)
    res = perceive(img)
    (dec,) = [c for c in res.crossings if c.objects[0] != c.objects[1]]
    assert dec.cue == 'edges' and dec.over is not None
    assert centreline_rms(res.objects[dec.over].points, curves[0])['rms_px'] < 1.0


def test_crossing_anchors_lie_past_the_widest_rod():
    """At a thin rod crossing a thick one the crossing's width is the thick rod's, and the thin rod's
    branch anchors lie outside the thick rod (where its skeleton runs straight again)."""
    import cv2
    from rod_deploy.perception.bending_energy_pairing import find_crossings, pair_crossings
    from rod_deploy.perception.skeleton_graph import build_skeleton_graph, prune_spurs, skeleton_of
    mask = np.zeros((300, 300), np.uint8)
    cv2.line(mask, (20, 150), (280, 150), 1, 15)                     # thick, along row 150
    cv2.line(mask, (80, 30), (220, 270), 1, 7)                       # thin, about 60 degrees to it
    graph = build_skeleton_graph(skeleton_of(mask.astype(bool)))
    prune_spurs(graph, 10.0)
    dist = cv2.distanceTransform(mask, cv2.DIST_L2, 3)
    width_at = lambda p: 2.0 * dist[tuple(np.round(p).astype(int).T)]      # noqa: E731
    crossings = find_crossings(graph, 5.0, 56.0, width_at=width_at, fit_px=12.0)
    (c,) = [c for c in crossings if len(c.branches) == 4]
    assert abs(c.width_px - 15.0) <= 2.0
    pair_crossings(graph, [c], 5.5, 12.0)
    thin = [b for b in c.branches if abs(b.tangent[0]) > 0.5]         # the thin rod's branches: steep
    assert len(thin) == 2
    assert all(abs(b.anchor[0] - 150.0) > 7.5 for b in thin)


def test_an_end_running_on_into_another_colour_is_trimmed():
    """A rod's skeleton running on past its end into a dark texture blob of another colour is cut back;
    a rod of one colour is left alone."""
    from rod_deploy.perception.traversal import TracedObject, trim_foreign_ends
    pts = np.stack([np.full(301, 100.0), np.arange(301.0)], axis=1)

    def colours_at(p):                   # red rod up to column 285, a purple blob beyond
        out = np.tile([50.0, 40.0], (len(p), 1))
        out[p[:, 1] > 285] = [15.0, -20.0]
        return out
    trimmed = trim_foreign_ends(TracedObject(pts.copy()), colours_at, 8.0, 12.0)
    assert 283 <= trimmed.points[-1, 1] <= 286 and trimmed.points[0, 1] == 0
    same = TracedObject(pts.copy())
    assert trim_foreign_ends(same, lambda p: np.tile([50.0, 40.0], (len(p), 1)), 8.0, 12.0) is same


@pytest.mark.parametrize('colour, length', [((230, 60, 230), 120), ((40, 200, 240), 80)])
def test_small_rod_on_a_strongly_textured_table_is_found_in_the_evidence_tail(colour, length):
    """A short rod on a strongly textured table: Otsu's split of the evidence separates the texture's
    blotches (the classes differ by < 20 grey levels, segmentation alone finds nothing); the pipeline
    splits the upper class again and finds the rod. An empty textured table still yields nothing."""
    from rod_deploy.perception.pipeline import PerceptionError, tail_threshold
    from rod_deploy.perception.segmentation import SegmentationError, segment
    t = np.linspace(0, 1, 200)
    curve = np.stack([150 + length * t, 300 + 0.5 * length * t + 10 * np.sin(3 * t)], axis=1)
    img = render_rod_scene((480, 640), [curve], [7.0], [colour], [], background=(120, 140, 110), texture=10.0,
                           gradient=0.2, ambient=0.5, seed=3)
    with pytest.raises(SegmentationError, match='contrast'):
        segment(img)
    res = perceive(img)
    assert len(res.objects) == 1
    assert centreline_rms(res.objects[0].points, curve)['rms_px'] < 1.0
    empty = render_rod_scene((480, 640), [], [], [], [], background=(120, 140, 110), texture=12.0, gradient=0.2,
                             seed=3)
    assert tail_threshold(empty) is None
    with pytest.raises(PerceptionError):
        perceive(empty)


@pytest.mark.parametrize('past_px, angle_deg', [(3.0, 0.0), (5.0, 20.0)])
def test_rod_end_lying_on_another_rod_is_placed_by_colour(past_px, angle_deg):
    """A rod whose end lies on top of another rod of another colour leaves a T in the skeleton: its path
    starts at the unpaired branch's anchor, short of the end (or the evidence-based end placement runs it
    on through the other rod). Its end is placed half a width inside where its own colour ends."""
    b = np.stack([np.full(400, 200.0), np.linspace(40, 560, 400)], axis=1)
    length = 150.0 + past_px
    t = np.linspace(0, 1, 300)
    a = np.stack([50.0 + length * t, 300.0 + np.tan(np.radians(angle_deg)) * length * t], axis=1)
    cs = curve_crossings([a, b])
    for c in cs:
        c.over = 0                                  # a on top
    img = render_rod_scene((320, 600), [a, b], [12.0, 7.0], [(200, 80, 200), (30, 30, 190)], cs,
                           background=(110, 120, 100), texture=4.0, seed=2)
    res = perceive(img)
    assert len(res.objects) == 2
    end_error = min(min(np.linalg.norm(o.points[0] - a[-1]), np.linalg.norm(o.points[-1] - a[-1]))
                    for o in res.objects)
    assert end_error < 4.0                          # without the rule: 13-18 px


def _lens_mask():
    """Two rods 7 px wide meeting at a shallow angle, lying side by side (touching) for 120 px and parting
    again: one from the upper left to the upper right, one from the lower left to the lower right."""
    import cv2
    mask = np.zeros((200, 400), np.uint8)
    cv2.polylines(mask, [np.array([(20, 40), (140, 97), (260, 97), (380, 40)], np.int32)], False, 1, 7)
    cv2.polylines(mask, [np.array([(20, 160), (140, 104), (260, 104), (380, 160)], np.int32)], False, 1, 7)
    return mask


def test_a_chain_carrying_two_rods_side_by_side_is_one_crossing_paired_side_by_side():
    """Two Ys joined by a chain as wide as both rods together (a lens: two rods crossing twice, or touching
    along a stretch) form one crossing, whatever the chain's length; its branches are paired on the same
    side of the chain (a rod crosses to the other side at the first crossing and back at the second), not
    by bending energy, which would run straight on from the upper left to the lower right."""
    import cv2
    from rod_deploy.perception.bending_energy_pairing import find_crossings, pair_crossings
    from rod_deploy.perception.skeleton_graph import build_skeleton_graph, skeleton_of
    mask = _lens_mask()
    graph = build_skeleton_graph(skeleton_of(mask.astype(bool)))
    dist = cv2.distanceTransform(mask, cv2.DIST_L2, 3)
    crossings = find_crossings(graph, 6.0, 64.0, width_at=lambda p: 2.0 * dist[tuple(np.round(p).astype(int).T)],
                               fit_px=12.0)
    lens = [c for c in crossings if c.doubled_edge is not None]
    assert len(lens) == 1 and len(lens[0].branches) == 4
    pair_crossings(graph, crossings, 6.0, 12.0)
    c = lens[0]
    for i, j in c.pairs:        # each pair: one branch on the left, one on the right, both above or both below
        far = [graph.branch_points(c.branches[k].edge, c.branches[k].side)[-1] for k in (i, j)]
        assert (far[0][0] < 100) == (far[1][0] < 100)
        assert (far[0][1] < 200) != (far[1][1] < 200)


def test_a_chain_of_one_rod_between_two_ys_is_not_doubled():
    """One rod with two short rods ending on it from the same side leaves two Ys joined by a chain of
    the rod's own width: not a chain of two rods side by side."""
    import cv2
    from rod_deploy.perception.bending_energy_pairing import find_crossings
    from rod_deploy.perception.skeleton_graph import build_skeleton_graph, skeleton_of
    mask = np.zeros((200, 400), np.uint8)
    cv2.line(mask, (20, 100), (380, 100), 1, 9)
    cv2.line(mask, (140, 100), (90, 20), 1, 9)
    cv2.line(mask, (260, 100), (310, 20), 1, 9)
    graph = build_skeleton_graph(skeleton_of(mask.astype(bool)))
    dist = cv2.distanceTransform(mask, cv2.DIST_L2, 3)
    crossings = find_crossings(graph, 6.0, 64.0, width_at=lambda p: 2.0 * dist[tuple(np.round(p).astype(int).T)],
                               fit_px=15.0)
    assert not any(c.doubled_edge is not None for c in crossings)


def test_two_rods_crossing_twice_with_a_lens_between_are_read_whole():
    """Generated scene cross_twice 900007 (development data): the rods cross twice 80 px apart and lie side
    by side in between; each came back as half of one rod and half of the other (RMS 57-64 px) when the two
    Ys were left as separate crossings, each with an unpaired branch."""
    sc = crossing_scene('cross_twice', 900_007)
    res = perceive(sc.image)
    assert len(res.objects) == 2
    for curve in sc.curves:
        assert min(centreline_rms(o.points, curve)['rms_px'] for o in res.objects) < 1.0
        assert min(arc_length_error(o.points, curve)['mean_px'] for o in res.objects) < 2.0


@pytest.mark.parametrize('profile, crossings', [
    ([7, 7, 8, 7, 9, 11, 13, 14, 14, 14, 13, 14, 12, 10, 8, 7, 7, 8, 8], 2),    # a lens: narrow at both ends
    ([13, 13, 14, 13, 14, 12, 10, 8, 7, 7, 7, 9, 11, 13, 14, 13, 14, 14], 1),   # side by side, crossing once
    ([14, 14, 13, 14, 14, 13, 14, 14, 13, 14, 14, 13, 14, 14], 0),               # touching all along
    ([14, 14, 13, 14, 14, 8, 14, 14, 13, 14, 14, 13, 14, 14], 0)])               # one noisy point
def test_overlaps_along_a_chain_of_two_rods_count_the_crossings(profile, crossings):
    """Where two rods lying side by side overlap, the mask narrows to one rod's width (here 7 px): each such
    neck along the chain (running median of 3) is a crossing, and the parity says whether a rod leaves on
    the side it came in on."""
    from rod_deploy.perception.bending_energy_pairing import overlaps_along
    widths = np.array([0, 0] + profile + [0, 0], float)     # the junctions' points at both ends are skipped
    points = np.stack([np.arange(len(widths), dtype=float), np.zeros(len(widths))], axis=1)
    width_at = lambda p: widths[p[:, 0].astype(int)] + 1.0  # noqa: E731  (the mask's 2 d, one more than the width)
    assert overlaps_along(points, [8.0, 8.0, 8.0, 8.0], width_at) == crossings


def test_a_rod_with_a_filled_loop_and_a_spur_into_it_is_one_object():
    """A generated self-loop scene (development seed 11300011: a grey rod 12.6 px wide whose loop the mask
    fills): thinning left a dead-end branch into the blob's bulge, which took the lead-in's place at the
    junction, so the rod came back in two pieces (2 objects). Without it the path runs through the blob
    and the loop is re-traced round it."""
    sc = crossing_scene('self_loop', 11_300_011)
    res = perceive(sc.image)
    assert len(res.objects) == 1
    assert centreline_rms(res.objects[0].points, sc.curves[0])['rms_px'] <= 1.0


def test_a_loop_in_the_shadow_of_its_own_crossing_is_not_cut_off():
    """A generated letter 'e' (development seed 10200013: a magenta rod): at the loop's crossing the lower
    strand lies in the upper one's shadow, 16 a*b* units off its lit colour; scored as a colour change, the
    pairing closed the loop on itself and sent the lead-in straight on to the tail (a closed object and an
    open one)."""
    sc = crossing_scene('letter_e', 10_200_013)
    res = perceive(sc.image)
    assert not any(o.closed for o in res.objects)
    best = min(res.objects, key=lambda o: centreline_rms(o.points, sc.curves[0])['rms_px'])
    assert best.length_px() > 0.85 * arc_length(sc.curves[0])[-1]


@pytest.mark.parametrize('light_azimuth_rad', [0.3, 1.9])
def test_wide_shaded_rod_beside_a_thin_one_is_centred_on_a_grey_table(light_azimuth_rad):
    """A 13 px pink rod and a 6 px orange one on a grey table: the shaded flank of the pink rod is about as
    bright as the table, so its mask and its evidence stop short of that flank, and w (the scene's, about 7
    px) gave profiles too short to reach it. The path was 0.7-2.3 px off along the whole rod and its width
    8-10 px; with profiles as wide as the rod's own mask and the edges of its share of the light it lies
    within 0.5 px RMS and its width within 0.6 px."""
    t = np.linspace(0.0, 1.0, 400)
    wide = np.stack([150 + 40 * np.sin(2.5 * t), 60 + 480 * t], axis=1)
    thin = np.stack([330 - 30 * np.sin(2.0 * t), 60 + 480 * t], axis=1)
    image = render_rod_scene((400, 600), [wide, thin], [13.0, 6.0], [(230, 120, 200), (40, 170, 230)], [],
                             background=(121, 103, 122), texture=3.0, light_azimuth_rad=light_azimuth_rad,
                             ambient=0.5, shadow_strength=0.5, seed=3)
    res = perceive(image)
    assert len(res.objects) == 2
    best = min(res.objects, key=lambda o: centreline_rms(o.points, wide)['rms_px'])
    assert centreline_rms(best.points, wide)['rms_px'] <= 0.5
    assert abs(best.width_px - 13.0) <= 0.6
