"""End to end on synthetic images with known centrelines: image -> ordered paths (pipeline.perceive)."""
import numpy as np
import pytest

from rod_deploy.perception.evaluation import centreline_rms, instance_dice, render_instances
from rod_deploy.perception.overlay import draw_overlay
from rod_deploy.perception.pipeline import PerceptionConfig, PerceptionError, perceive
from rod_deploy.perception.synthetic import draw_strokes, example_curves, stroke_coverage

PINK, YELLOW, INK = (90, 90, 230), (60, 220, 200), (40, 30, 30)
CURVES = example_curves(500)


def drawn(curves, widths, colours, shape=(500, 500), **kw):
    return draw_strokes(shape, curves, widths, colours, **kw)


@pytest.mark.parametrize('width', [3.0, 6.0, 12.0])
def test_drawn_stroke_centreline_within_a_pixel(width):
    curve = CURVES['sine']
    res = perceive(drawn([curve], [width], [INK], gradient=0.2, noise_std=3, blur_sigma=0.7))
    (obj,) = res.objects
    err = centreline_rms(obj.points, curve)
    assert err['rms_px'] < 1.0 and err['end_error_px'] < 1.5
    assert abs(obj.width_px - width) < 1.0
    assert obj.points[0, 1] < obj.points[-1, 1]                      # starts at the leftmost end
    assert np.allclose(np.hypot(*np.diff(obj.points, axis=0).T)[:-1], 1.0, atol=0.02)   # 1 px spacing


def test_self_crossing_loop_is_one_ordered_path():
    curve = CURVES['alpha']
    res = perceive(drawn([curve], [7.0], [INK], noise_std=3, blur_sigma=0.7))
    (obj,) = res.objects
    assert not obj.closed
    assert centreline_rms(obj.points, curve)['rms_px'] < 1.0
    # ordered: the path visits the curve's points in sequence (monotone along the reference)
    ref_t = [int(np.argmin(np.hypot(*(curve - p).T))) for p in obj.points[::25]]
    assert np.all(np.diff(ref_t) > 0) or np.all(np.diff(ref_t) < 0)
    assert len(res.crossings) == 1 and res.crossings[0].objects == (0, 0)


def test_closed_loop_is_closed():
    res = perceive(drawn([CURVES['circle']], [6.0], [INK], noise_std=2))
    (obj,) = res.objects
    assert obj.closed and np.allclose(obj.points[0], obj.points[-1])
    assert centreline_rms(obj.points, CURVES['circle'])['rms_px'] < 1.0


def two_rods(seam=False):
    a = np.stack([np.linspace(60, 440, 400), 100 + 0.6 * np.linspace(0, 380, 400)], axis=1)
    b = np.stack([np.linspace(250, 260, 400), np.linspace(30, 470, 400)], axis=1)
    if seam:   # a dark outline around the upper rod cuts the lower one, as a shadow does
        return drawn([a, b, b], [10.0, 16.0, 12.0], [PINK, (5, 5, 5), YELLOW], background=(15, 15, 15),
                     noise_std=3, blur_sigma=0.8), a, b
    return drawn([a, b], [10.0, 12.0], [PINK, YELLOW], background=(15, 15, 15), noise_std=3,
                 blur_sigma=0.8), a, b


@pytest.mark.parametrize('seam', [False, True])
def test_two_coloured_rods_crossing_with_over_under(seam):
    img, a, b = two_rods(seam)
    res = perceive(img)
    assert len(res.objects) == 2
    lengths = [o.length_px() for o in res.objects]
    assert lengths[0] >= lengths[1]
    k_b = int(np.argmin([centreline_rms(o.points, b)['rms_px'] for o in res.objects]))
    k_a = 1 - k_b
    assert centreline_rms(res.objects[k_a].points, a)['rms_px'] < 1.0
    assert centreline_rms(res.objects[k_b].points, b)['rms_px'] < 1.0
    (crossing,) = [c for c in res.crossings if c.objects[0] != c.objects[1]]
    assert crossing.over == k_b and crossing.confidence > 0.5          # the yellow rod, drawn last, is on top
    gt = np.zeros(img.shape[:2], np.uint8)
    gt[stroke_coverage(img.shape, a, 10.0) >= 0.5] = 1
    gt[stroke_coverage(img.shape, b, 12.0) >= 0.5] = 2
    pooled, _, _ = instance_dice(render_instances(res.objects, res.crossings, img.shape), gt)
    assert pooled > 0.95


def test_several_strokes_and_the_overlay():
    curves = [CURVES['letter_u'] * 0.5 + [20, 20], CURVES['sine'] * 0.5 + [250, 250]]
    img = drawn(curves, [5.0, 5.0], [INK, INK], noise_std=2)
    res = perceive(img)
    assert len(res.objects) == 2
    ov = draw_overlay(img, res.objects, res.crossings, metres_per_px=0.001)
    assert ov.shape == img.shape and ov.dtype == np.uint8
    from rod_deploy.perception.overlay import PALETTE, scale_bar_length_m
    for k, o in enumerate(res.objects):          # each path is drawn in its own colour where it was perceived
        rows, cols = np.round(o.points[5:-5:7]).astype(int).T
        colours = ov[rows, cols].astype(int)
        on_path = np.all(np.abs(colours - PALETTE[k]) <= 60, axis=1)
        assert on_path.mean() > 0.8, (k, on_path.mean())
    # away from every path and the legend, the image is only dimmed
    far = (slice(img.shape[0] // 2 - 10, img.shape[0] // 2 + 10), slice(img.shape[1] - 30, img.shape[1] - 5))
    np.testing.assert_allclose(ov[far], (img[far].astype(np.float32) * 0.55).astype(np.uint8), atol=1)
    # a metric scale bar (bottom left) only with a mapping: 100 mm for this 0.001 m/px, 500 px wide image
    assert scale_bar_length_m(0.001, img.shape[1]) == pytest.approx(0.1)
    plain = draw_overlay(img, res.objects, res.crossings)
    h = img.shape[0]
    unit = max(1, int(round(min(img.shape[:2]) / 450)))
    bar = (slice(h - 14 * unit, h - 12 * unit), slice(12 * unit, 12 * unit + 90))
    assert np.all(ov[bar] == 255) and not np.all(plain[bar] == 255)


def test_no_stroke_and_huge_images():
    with pytest.raises(PerceptionError, match='no stroke'):
        perceive(np.full((200, 200, 3), 200, np.uint8))
    curve = CURVES['sine'] * 4
    img = drawn([curve], [16.0], [INK], shape=(2000, 2000), noise_std=2)
    res = perceive(img, PerceptionConfig(max_pixels=1_000_000))
    assert res.scale == pytest.approx(0.5) and len(res.objects) == 1
    assert centreline_rms(res.objects[0].points, curve)['rms_px'] < 2.0   # in full-resolution pixels


def test_rods_touching_end_to_end_are_told_apart_by_colour():
    a = np.stack([np.linspace(80, 250, 200), np.linspace(60, 250, 200)], axis=1)
    b = np.stack([np.linspace(250, 420, 200), np.linspace(250, 440, 200)], axis=1)   # continues a smoothly
    img = drawn([a, b], [10.0, 10.0], [PINK, (200, 200, 60)], background=(15, 15, 15), noise_std=3)
    res = perceive(img)
    assert len(res.objects) == 2
    for curve in (a, b):
        assert min(centreline_rms(o.points, curve)['rms_px'] for o in res.objects) < 3.0


def straight(p0, p1, n=300):
    return np.stack([np.linspace(p0[0], p1[0], n), np.linspace(p0[1], p1[1], n)], axis=1)


def assert_each_rod_found(res, curves, max_rms_px):
    assert len(res.objects) == len(curves)
    for curve in curves:
        assert min(centreline_rms(o.points, curve)['rms_px'] for o in res.objects) < max_rms_px


def test_three_rods_crossing_near_one_point_are_one_crossing():
    # the skeleton splits such a crossing into several junction clusters around the overlap (two of
    # them three-way): they have to be joined into one crossing of six branches
    def through(centre, degrees, half=220):
        d = np.array([np.sin(np.radians(degrees)), np.cos(np.radians(degrees))])
        return straight(np.array(centre) - half * d, np.array(centre) + half * d)

    curves = [through((250, 300), 0), through((244, 296), 60), through((256, 306), 120)]
    img = drawn(curves, [11.0, 12.0, 10.0], [PINK, YELLOW, (200, 200, 60)], shape=(500, 600),
                background=(15, 15, 15), noise_std=3, blur_sigma=0.8)
    assert_each_rod_found(perceive(img), curves, 1.0)


def test_rod_end_lying_along_another_rod_does_not_cut_it():
    # a yellow rod comes in at a shallow angle and its last 130 px lie along (on top of) a cyan rod: the
    # cyan rod is hidden there, and its two visible parts (same colour, the stretch between them covered)
    # are one rod
    lower = straight((250, 40), (250, 560), 520)
    slope = np.radians(15)
    upper = np.vstack([straight((250 + 180 * np.sin(slope), 200 - 180 * np.cos(slope)), (254, 200), 200)[:-1],
                       straight((254, 200), (254, 330), 130)])
    img = drawn([lower, upper], [10.0, 12.0], [(200, 200, 60), YELLOW], shape=(500, 600),
                background=(15, 15, 15), noise_std=3, blur_sigma=0.8)
    assert_each_rod_found(perceive(img), [lower, upper], 2.5)
