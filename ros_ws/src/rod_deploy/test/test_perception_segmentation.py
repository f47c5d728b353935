"""Segmentation: ink on paper, coloured rods on dark and textured tables, and images without objects."""
import numpy as np
import pytest

from rod_deploy.perception.segmentation import SegmentationConfig, SegmentationError, foreground_evidence, segment
from rod_deploy.perception.synthetic import draw_strokes, example_curves, stroke_coverage

SHAPE = (300, 400)
CURVE = example_curves(300)['sine'] * [1.0, 400 / 300]


def iou(a, b):
    return (a & b).sum() / (a | b).sum()


@pytest.mark.parametrize('background, colour, kw', [
    ((235, 235, 230), (40, 30, 30), dict(gradient=0.3)),            # dark ink, uneven light on paper
    ((235, 235, 230), (200, 80, 20), dict()),                        # blue ballpoint
    ((15, 15, 15), (90, 90, 230), dict()),                           # pink rod on a dark table
    ((120, 100, 80), (60, 220, 200), dict(texture=8.0)),             # yellow rod on a textured table
])
def test_mask_matches_the_drawn_stroke(background, colour, kw):
    width = 9.0
    img = draw_strokes(SHAPE, [CURVE], [width], [colour], background=background, noise_std=3, **kw)
    seg = segment(img)
    truth = stroke_coverage(SHAPE, CURVE, width) >= 0.5
    assert iou(seg.mask, truth) > 0.85
    assert 0.5 * width < seg.stroke_width_px < 1.5 * width


def test_dark_only_polarity_ignores_bright_marks():
    img = draw_strokes(SHAPE, [CURVE, np.array([[50.0, 50.0], [50.0, 150.0]])], [6, 10],
                       [(30, 30, 30), (255, 255, 255)], background=(150, 150, 150), noise_std=2)
    dark = segment(img, SegmentationConfig(method='dark')).mask
    both = segment(img).mask
    assert not dark[45:56, 60:140].any() and both[45:56, 60:140].any()


@pytest.mark.parametrize('image, message', [
    (np.full((100, 120, 3), 128, np.uint8), 'uniform'),
    (np.zeros((0, 10, 3), np.uint8), 'empty'),
    (np.random.default_rng(0).normal(128, 2, (100, 120)).clip(0, 255).astype(np.uint8), 'no stroke'),
])
def test_no_object_is_a_clear_error(image, message):
    with pytest.raises(SegmentationError, match=message):
        segment(image)


def test_config_is_validated():
    with pytest.raises(ValueError, match='method'):
        SegmentationConfig(method='magic')


def test_foreground_evidence_is_the_largest_channel_difference():
    rng = np.random.default_rng(3)
    bgr = rng.integers(0, 256, (31, 47, 3), dtype=np.uint8)
    image_background = rng.integers(0, 256, (31, 47, 3), dtype=np.uint8)
    diff_image = bgr.astype(int) - image_background.astype(int)
    colour = (12.4, 200.6, 99.5)                      # rounded to (12, 201, 100), as Python rounds
    diff_colour = bgr.astype(int) - np.array([12, 201, 100])
    for background, diff in ((image_background, diff_image), (colour, diff_colour)):
        for method, expected in (('contrast', np.abs(diff)), ('dark', -diff), ('bright', diff)):
            s = foreground_evidence(bgr, background, method)
            assert s.dtype == np.uint8 and s.shape == bgr.shape[:2]
            np.testing.assert_array_equal(s, np.clip(expected.max(axis=2), 0, 255))
