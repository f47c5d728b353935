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
