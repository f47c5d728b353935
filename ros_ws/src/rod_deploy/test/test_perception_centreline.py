"""Sub-pixel edges across a path: the compiled edge search on profiles with known edges."""
import numpy as np
from scipy.special import erf

from rod_deploy.perception.centreline import edge_positions


def test_edges_of_blurred_bars_are_found_to_a_tenth_of_a_pixel():
    offsets = np.arange(-10.0, 10.0 + 1e-9, 0.5)
    shifts = np.linspace(-1.2, 1.2, 13)
    half_widths = np.linspace(2.0, 4.5, 13)
    x = offsets[None, :] - shifts[:, None]
    bars = 60 * (erf((x + half_widths[:, None]) / 1.2) - erf((x - half_widths[:, None]) / 1.2)) + 5
    e_l, e_r = edge_positions(bars.astype(np.float32), offsets, floor=20.0, core_px=3.0)
    np.testing.assert_allclose(e_l, shifts - half_widths, atol=0.1)
    np.testing.assert_allclose(e_r, shifts + half_widths, atol=0.1)


def test_no_edge_where_the_profile_never_falls_or_the_centre_is_background():
    offsets = np.arange(-6.0, 6.0 + 1e-9, 0.5)
    flat = np.full((1, offsets.size), 100.0, np.float32)               # object everywhere: no boundary
    dark = np.where(np.abs(offsets) > 2, 100.0, 0.0)[None].astype(np.float32)   # background at the centre
    one_sided = np.where(offsets < 3, 100.0, 0.0)[None].astype(np.float32)     # falls on the right only
    for profile in (flat, dark, one_sided):
        e_l, e_r = edge_positions(profile, offsets, floor=20.0, core_px=2.0)
        assert np.isnan(e_l[0]) and np.isnan(e_r[0])


def test_free_end_is_placed_at_the_rod_not_at_its_shadow_beyond():
    """A rod's shadow beyond its free end holds the evidence at 20-30 % of the rod's: the end goes half a
    width inside the rod's own boundary, not left where thinning ran out (nor at the shadow's edge)."""
    import cv2

    from rod_deploy.perception.centreline import RefinedPath, place_ends
    width, tip_col = 11, 100.0
    for shadow in (0.2, 0.3):
        evidence = np.zeros((100, 200), np.float32)
        evidence[45:56, 20:100] = 200.0                     # the rod, its flat end at column 100
        evidence[45:56, 100:135] = shadow * 200.0           # its shadow on the table beyond the end
        evidence = cv2.GaussianBlur(evidence, (7, 7), 1.2)
        pts = np.c_[np.full(71, 50.0), np.linspace(30.0, tip_col, 71)]       # thinning reached the tip
        out = place_ends(RefinedPath(pts, float(width), False, np.full(71, np.nan)), evidence, 10.0,
                         0.5 * width, float(width)).points
        assert abs(out[-1, 1] - (tip_col - 0.5 * width)) < 1.0, (shadow, out[-1])
        assert abs(out[-1, 0] - 50.0) < 0.5


def test_free_end_found_where_thinning_stopped_about_a_width_short_of_the_tip():
    """Thinning can stop about a width inside a rod's free end, so that the first ray search (trimmed
    stretch + 2 half widths + 4 px) ends just before the tip: the second, one width further, finds the
    boundary and the end goes half a width inside it (it was left 8-13 px short)."""
    import cv2

    from rod_deploy.perception.centreline import RefinedPath, place_ends
    for width in (9, 13):
        tip_col = 150.0
        evidence = np.zeros((100, 220), np.float32)
        evidence[50 - width // 2:51 + width // 2, 20:int(tip_col)] = 200.0
        evidence = cv2.GaussianBlur(evidence, (7, 7), 1.2)
        short = tip_col - 0.5 * width - 1.2 * width          # the skeleton's end, a width inside the tip
        pts = np.c_[np.full(81, 50.0), np.linspace(30.0, short, 81)]
        out = place_ends(RefinedPath(pts, float(width), False, np.full(81, np.nan)), evidence, 10.0,
                         0.5 * width, float(width)).points
        assert abs(out[-1, 1] - (tip_col - 0.5 * width)) < 1.0, (width, out[-1])
        assert abs(out[-1, 0] - 50.0) < 0.5
