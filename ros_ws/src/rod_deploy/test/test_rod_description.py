"""Rod description YAML (CONTRACTS.md section 4)."""
import math

import pytest

from rod_deploy.planning.rod_description import RodDescriptionError, load_rod_description, rod_description_from_dict
from rod_deploy.planning.scaling import LOOP_HEIGHT_COEFFICIENT


def test_l_gb_given():
    rod = rod_description_from_dict({'length': 0.9, 'radius': 0.002, 'L_gb': 0.034, 'friction': 0.4})
    assert rod.gravito_bending_length_m == 0.034
    assert rod.ks_bar == pytest.approx(4 * 0.034 ** 2 / 0.002 ** 2)
    assert rod.length_bar == pytest.approx(0.9 / 0.034)
    assert rod.friction == 0.4


def test_loop_height_and_material():
    rod = rod_description_from_dict({'length': 1.0, 'radius': 0.002, 'loop_height': 0.03})
    assert rod.gravito_bending_length_m == pytest.approx(0.03 / LOOP_HEIGHT_COEFFICIENT)
    rod = rod_description_from_dict({'length': 1.0, 'radius': 0.002, 'youngs_modulus': 1.0e6, 'density': 1180})
    assert rod.gravito_bending_length_m == pytest.approx((1e6 * 0.002 ** 2 / (8 * 1180 * 9.81)) ** (1 / 3))


def test_hanging_height_includes_the_stretch_under_its_own_weight():
    """A rod hanging at rest with its free end just touching the table: the held node at h + L + rho g L^2 / (2 E)
    (the tension rho A g s stretches each element by rho g s / E)."""
    rod = rod_description_from_dict({'length': 0.8, 'radius': 0.002, 'youngs_modulus': 1.0e6, 'density': 1180})
    assert rod.hanging_height_m == pytest.approx(0.002 + 0.8 + 1180 * 9.81 * 0.8 ** 2 / (2 * 1.0e6), rel=1e-12)


@pytest.mark.parametrize('d, words', [
    ({'radius': 0.002, 'L_gb': 0.03}, 'missing "length"'),
    ({'length': 1, 'radius': 0.002}, 'needs one of'),
    ({'length': 1, 'radius': -0.002, 'L_gb': 0.03}, '"radius" must be positive'),
    ({'length': 1, 'radius': 0.002, 'L_gb': math.nan}, '"L_gb" must be positive'),
    ({'length': 1, 'radius': 0.002, 'L_gb': 0.03, 'colour': 'red'}, 'unknown field'),
    ({'length': 0.05, 'radius': 0.002, 'L_gb': 0.03}, 'not longer than 2 L_gb'),
    ({'length': 1, 'radius': 0.002, 'L_gb': 'abc'}, 'must be a number'),
])
def test_bad_descriptions(d, words):
    with pytest.raises(RodDescriptionError, match=words):
        rod_description_from_dict(d)


def test_file_errors(tmp_path):
    with pytest.raises(RodDescriptionError, match='cannot read'):
        load_rod_description(tmp_path / 'missing.yaml')
    p = tmp_path / 'bad.yaml'
    p.write_text('length: [1\n')
    with pytest.raises(RodDescriptionError, match='not valid YAML'):
        load_rod_description(p)
    p.write_text('length: 0.9\nradius: 0.002\nL_gb: 0.034\n')
    assert load_rod_description(p).length_m == 0.9
