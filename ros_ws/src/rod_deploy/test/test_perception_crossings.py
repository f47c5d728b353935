"""Crossings and loops: the synthetic crossing scenes, over/under from occlusion edges, shadow strands,
and ordered paths through self crossings, a rod under a loop and two rods crossing twice."""
import numpy as np
import pytest

from rod_deploy.perception.crossing_order import occlusion_edge_strength
from rod_deploy.perception.crossing_scenes import (TrueCrossing, crossing_scene, curve_crossings, knot_curve,
                                                   render_rod_scene)
from rod_deploy.perception.evaluation import arc_length_error, centreline_rms
from rod_deploy.perception.path_io import deployed_order
from rod_deploy.perception.pipeline import perceive
from rod_deploy.perception.traversal import TracedObject, drop_shadow_strands


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


def test_deployed_order_starts_at_the_named_end():
    p = np.stack([np.linspace(0, 1, 11), np.zeros(11)], axis=1)
    assert np.allclose(deployed_order(p, False, (0.9, 0.1))[0], [1, 0])
    assert np.allclose(deployed_order(p, False, None), p)
    ring = np.vstack([np.stack([np.cos(t), np.sin(t)], axis=1) for t in [np.linspace(0, 2 * np.pi, 9)[:-1]]])
    closed = np.vstack([ring, ring[:1]])
    out = deployed_order(closed, True, (0.0, -1.1))
    assert np.allclose(out[0], [0, -1], atol=1e-9) and np.allclose(out[0], out[-1]) and len(out) == 9
