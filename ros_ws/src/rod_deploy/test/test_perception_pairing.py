"""Bending-energy pairing: straight continuations win, U-turns lose, odd counts leave one end."""
import numpy as np
import pytest

from rod_deploy.perception.bending_energy_pairing import (Branch, colours_differ, minimal_energy_pairing, pair_energy,
                                                          paints_differ)


def branch(angle_deg, dist=10.0, colour=None):
    """A branch leaving the origin at ``angle_deg``; its tangent points back into the crossing."""
    a = np.radians(angle_deg)
    u = np.array([np.sin(a), np.cos(a)])
    return Branch(0, 0, dist * u, 3, -u, None if colour is None else np.asarray(colour, float))


@pytest.mark.parametrize('crossing_angle', [25, 45, 70, 90])
def test_x_crossing_pairs_opposite_branches(crossing_angle):
    bs = [branch(0), branch(crossing_angle), branch(180), branch(180 + crossing_angle)]
    pairs, _ = minimal_energy_pairing(bs)
    assert sorted(tuple(sorted(p)) for p in pairs) == [(0, 2), (1, 3)]


def test_straight_is_cheaper_than_a_turn():
    assert pair_energy(branch(0), branch(180)) < 1e-9
    straight, turn, hairpin = (pair_energy(branch(0), branch(a)) for a in (180, 120, 30))
    assert straight < turn < hairpin


def test_t_junction_leaves_the_stem_unpaired():
    bs = [branch(0), branch(180), branch(90)]
    pairs, _ = minimal_energy_pairing(bs)
    assert [tuple(sorted(p)) for p in pairs] == [(0, 1)]


def test_colour_overrides_a_slightly_straighter_wrong_pairing():
    red, yellow = (50, 30), (-25, 70)
    # a shallow crossing where geometry alone is ambiguous (branches 10 degrees apart)
    bs = [branch(0, colour=red), branch(10, colour=yellow), branch(185, colour=yellow), branch(195, colour=red)]
    pairs, _ = minimal_energy_pairing(bs)
    assert sorted(tuple(sorted(p)) for p in pairs) == [(0, 3), (1, 2)]


def test_a_rod_in_the_shadow_of_the_strand_above_is_one_paint():
    lit, shade = (43.0, -37.0), (31.0, -27.0)            # a magenta rod (letter_e 10200013's loop crossing)
    assert colours_differ(np.array(lit), np.array(shade), 12.0)                # 16 apart
    assert not paints_differ(np.array(lit), np.array(shade), 12.0)             # one hue, less chroma
    assert paints_differ(np.array(lit), np.array((30.0, 20.0)), 12.0)          # another hue
    assert paints_differ(np.array(lit), np.array((-1.0, 2.0)), 12.0)           # grey (a shadow on the table)
    assert paints_differ(np.array(lit), np.array((11.0, -8.4)), 12.0)          # one hue, 1/4 the chroma: not a shade
    assert not paints_differ(np.array((1.0, -2.0)), np.array((-1.0, 2.0)), 12.0)


@pytest.mark.parametrize('crossing_angle', [40, 60])
def test_shade_next_to_a_crossing_does_not_break_the_straight_pairing(crossing_angle):
    """One branch of the lower strand lies in the upper strand's shadow: its colour is 16 a*b* units off
    its straight partner's (darker, same hue) and 10 off the upper strand's (a little less lit). Scored as
    another colour, the straight pairing would cost the colour penalty and both strands would turn through
    the crossing (as in letter_e 10200013, whose loop was closed on itself and cut off its lead-in)."""
    lit, shade, upper = (43.0, -37.0), (31.0, -27.0), (39.0, -33.5)
    bs = [branch(0, colour=lit), branch(crossing_angle, colour=upper), branch(180, colour=shade),
          branch(180 + crossing_angle, colour=upper)]
    pairs, _ = minimal_energy_pairing(bs)
    assert sorted(tuple(sorted(p)) for p in pairs) == [(0, 2), (1, 3)]
