"""Two rods lying side by side along a stretch: each traced path moved onto its own rod
(rod_deploy.perception.side_by_side)."""
import cv2
import numpy as np
import pytest

from rod_deploy.perception.centreline import resample
from rod_deploy.perception.side_by_side import mask_edges, separate_side_by_side

W = 8            # both rods' width [px]


def _mask(*curves):
    mask = np.zeros((200, 240), np.uint8)
    for c in curves:
        cv2.polylines(mask, [np.round(np.asarray(c)[:, ::-1]).astype(np.int32)], False, 1, thickness=W)
    return mask.astype(bool)


def _poly(*points):
    return resample(np.array(points, float), 1.0)


def _rows_between(path, c0, c1):
    keep = (path[:, 1] >= c0) & (path[:, 1] <= c1)
    return path[keep, 0]


# rod A along row 100; rod B comes in from the upper left, lies against A's upper side (row 92) from column 70
# to 150 and leaves to the upper right: one strip 2 W wide there, whose middle (row 96) both traced paths follow
ROD_A = _poly((100, 10), (100, 230))
ROD_B = _poly((40, 20), (92, 70), (92, 150), (40, 200))
PATH_A = _poly((100, 10), (100, 62), (96, 72), (96, 148), (100, 158), (100, 230))
PATH_B = _poly((40, 20), (88, 62), (96, 72), (96, 148), (88, 158), (40, 200))


def test_mask_edges_are_the_strips_edges():
    mask = _mask(ROD_A)
    lo, hi = mask_edges(mask, np.array([[100.0, 100.0], [101.5, 120.0]]), np.array([[1.0, 0.0], [1.0, 0.0]]),
                        12.0)
    # OpenCV draws a thickness-8 line 9 px wide: rows 96..104, the 0.5 level half a pixel outside
    assert np.allclose(hi - lo, 9.0, atol=0.01)
    assert np.allclose(0.5 * (lo + hi), [0.0, -1.5], atol=0.01)


def test_paths_down_the_middle_of_two_rods_side_by_side_are_moved_onto_each_rod():
    mask = _mask(ROD_A, ROD_B)
    assert abs(np.median(_rows_between(PATH_A, 85, 135)) - 100.0) > 3.5        # half a width off before
    a, b = separate_side_by_side([PATH_A, PATH_B], [W, W], [False, False], mask)
    assert np.max(np.abs(_rows_between(a, 85, 135) - 100.0)) < 0.6
    assert np.max(np.abs(_rows_between(b, 85, 135) - 92.0)) < 0.6
    assert np.allclose(_rows_between(a, 10, 40), 100.0)                         # untouched where alone


def test_a_rod_ending_alongside_another_is_put_on_the_side_away_from_the_others_arm():
    # rod B ends lying against A's upper side (its path ends inside the strip): its side is seen where the rods
    # part on the left, B's arm leaving upwards; A runs on along row 100 past B's end
    rod_b = _poly((40, 20), (92, 70), (92, 130))
    path_b = _poly((40, 20), (88, 62), (96, 72), (96, 130))
    path_a = _poly((100, 10), (100, 62), (96, 72), (96, 130), (100, 140), (100, 230))
    mask = _mask(ROD_A, rod_b)
    a, b = separate_side_by_side([path_a, path_b], [W, W], [False, False], mask)
    assert np.max(np.abs(_rows_between(b, 85, 115) - 92.0)) < 0.6
    assert np.max(np.abs(_rows_between(a, 85, 115) - 100.0)) < 0.6


CROSSED_B = _poly((150, 20), (92, 66), (92, 150), (40, 200))


def _crossed_scene():
    """Rod B comes in from below A, crosses it at column 62 and then lies against A's upper side: seen from
    where the rods part on the left, B is on the wrong side of A for the stretch."""
    rod_b = CROSSED_B
    path_b = _poly((150, 20), (104, 56), (96, 70), (96, 148), (88, 158), (40, 200))
    path_a = _poly((100, 10), (100, 56), (96, 70), (96, 148), (100, 158), (100, 230))
    return _mask(ROD_A, rod_b), path_a, path_b


def _colours_at(points):
    """a*b* of the crossed scene: magenta nearer rod B's centreline, cyan nearer rod A's."""
    p = np.asarray(points, float)
    d_a = np.abs(p[:, 0] - 100.0)
    d_b = np.min(np.hypot(p[:, None, 0] - CROSSED_B[None, :, 0], p[:, None, 1] - CROSSED_B[None, :, 1]), axis=1)
    return np.where((d_b < d_a)[:, None], [[40.0, -30.0]], [[-30.0, -10.0]])


def test_rods_of_two_colours_take_their_sides_from_colour_even_past_a_crossing():
    mask, path_a, path_b = _crossed_scene()
    a, b = separate_side_by_side([path_a, path_b], [W, W], [False, False], mask, colours_at=_colours_at,
                                 crossings=[(0, 1, np.array([100.0, 62.0]))])
    assert np.max(np.abs(_rows_between(a, 90, 130) - 100.0)) < 0.6
    assert np.max(np.abs(_rows_between(b, 90, 130) - 92.0)) < 0.6


def test_one_colour_past_a_crossing_is_left_alone():
    mask, path_a, path_b = _crossed_scene()
    a, b = separate_side_by_side([path_a, path_b], [W, W], [False, False], mask,
                                 crossings=[(0, 1, np.array([100.0, 62.0]))])
    assert a is path_a and b is path_b


def test_paths_meeting_briefly_at_a_crossing_are_left_alone():
    rod_b = _poly((60, 20), (140, 220))             # crosses A at about 22 degrees
    path_b = rod_b.copy()
    mask = _mask(ROD_A, rod_b)
    a, b = separate_side_by_side([ROD_A, path_b], [W, W], [False, False], mask)
    assert a is ROD_A and b is path_b


def test_mismatched_inputs_are_refused():
    with pytest.raises(ValueError, match='2 paths, 1 widths'):
        separate_side_by_side([PATH_A, PATH_B], [W], [False, False], _mask(ROD_A))
