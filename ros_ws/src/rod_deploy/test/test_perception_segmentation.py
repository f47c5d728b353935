"""Segmentation: ink on paper, coloured rods on dark and textured tables, and images without objects."""
import numpy as np
import pytest

from rod_deploy.perception.segmentation import SegmentationConfig, SegmentationError, segment
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
