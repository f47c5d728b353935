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


def _shaded_rod_on_a_table(colour, table, light_azimuth_rad, width=13.0):
    """A straight, round, shaded rod (row 100, columns 40-360) casting a shadow on a plain table whose
    brightness its dim flank nearly matches (:func:`~rod_deploy.perception.crossing_scenes.render_rod_scene`)."""
    from rod_deploy.perception.crossing_scenes import render_rod_scene
    curve = np.c_[np.full(321, 100.0), np.linspace(40.0, 360.0, 321)]
    return curve, render_rod_scene((200, 400), [curve], [width], [colour], [], background=table, texture=0.0,
                                   gradient=0.0, light_azimuth_rad=light_azimuth_rad, ambient=0.5,
                                   shadow_strength=0.5, noise_std=2.0, seed=1)


def test_edges_of_the_rods_share_of_the_light_ignore_its_dim_flank_and_shadow():
    """A pink rod on a grey table, lit across: the evidence |I - B| of its shaded flank falls to about the
    table's level inside the rod and its shadow holds the evidence up beside it, so the evidence's edges are
    missing or off in most profiles, while the edges of the rod's share of the light (its colour split from
    the table's) are the true ones (median error at most 0.15 px, 80 % of them within 0.35 px), on both sides
    and with the light from either side."""
    from rod_deploy.perception.centreline import edge_profiles, rod_share_profiles
    from rod_deploy.perception.segmentation import segment
    for azimuth in (np.pi / 2, -np.pi / 2):
        curve, image = _shaded_rod_on_a_table((230, 120, 200), (121, 103, 122), azimuth)
        seg = segment(image)
        points = curve[40:281:10]
        normals = np.tile([1.0, 0.0], (len(points), 1))             # (row, col): across the rod
        evidence, offsets = edge_profiles(seg.evidence, points, normals, 14.0)
        share = rod_share_profiles(image, seg.background, points, normals, offsets, np.zeros(len(points), bool))
        assert share is not None
        e_l, e_r = edge_positions(share, offsets, 0.0, core_px=7.5)
        for error in (e_l + 6.5, e_r - 6.5):
            assert np.median(np.abs(error)) <= 0.15 and np.mean(np.abs(error) <= 0.35) >= 0.8, error
        v_l, v_r = edge_positions(evidence, offsets, 0.25 * seg.threshold, core_px=7.5)
        with np.errstate(invalid='ignore'):
            right = (np.abs(v_l + 6.5) <= 0.6) & (np.abs(v_r - 6.5) <= 0.6)
        assert right.mean() < 0.5, right.mean()


def test_no_rod_share_where_the_rod_has_the_tables_colour():
    """A grey rod on a grey table of the same chromaticity: no split of the colour (None), the evidence's
    edges are used."""
    from rod_deploy.perception.centreline import rod_share_profiles
    from rod_deploy.perception.segmentation import segment
    curve, image = _shaded_rod_on_a_table((220, 220, 220), (110, 110, 110), np.pi / 2)
    seg = segment(image)
    points = curve[40:281:10]
    normals = np.tile([1.0, 0.0], (len(points), 1))
    offsets = np.arange(-14.0, 14.0 + 1e-9, 0.5)
    assert rod_share_profiles(image, seg.background, points, normals, offsets, np.zeros(len(points), bool)) is None
