"""Bending-energy pairing: straight continuations win, U-turns lose, odd counts leave one end."""
import numpy as np
import pytest

from rod_deploy.perception.bending_energy_pairing import Branch, minimal_energy_pairing, pair_energy


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
