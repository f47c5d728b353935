"""``benchmarks/replay_probe.py --set name=value``: yes/no settings read from 0/1 (``bool('0')`` is True, which made
``--set hold_twist=0`` keep the twist held in our DER), numbers in the field's type, clear errors otherwise."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[4] / 'benchmarks'))
from replay_probe import with_settings  # noqa: E402

from rod_deploy.deployment.simulate import SimulationSettings  # noqa: E402


@pytest.mark.parametrize('text, want', [('0', False), ('false', False), ('No', False), ('off', False),
                                        ('1', True), ('True', True), ('yes', True), ('on', True)])
def test_yes_no_setting(text, want):
    s = with_settings(SimulationSettings(hold_twist=not want), {'hold_twist': text})
    assert s.hold_twist is want


def test_numbers_in_the_field_type_and_others_untouched():
    base = SimulationSettings()
    s = with_settings(base, {'dt_s': '0.005', 'max_step_halvings': '3'})
    assert s.dt_s == 0.005 and isinstance(s.dt_s, float)
    assert s.max_step_halvings == 3 and isinstance(s.max_step_halvings, int)
    assert s.hold_twist == base.hold_twist and s.friction_velocity_m_s == base.friction_velocity_m_s


@pytest.mark.parametrize('sets, words', [({'hold_twist': '2'}, 'yes/no'), ({'no_such': '1'}, 'no such setting'),
                                         ({'dt_s': 'fast'}, 'not a float'),
                                         ({'start_xy': '0,0'}, 'cannot be given')])
def test_bad_settings_are_errors(sets, words):
    with pytest.raises(SystemExit, match=words):
        with_settings(SimulationSettings(), sets)


def test_friction_a_level_name_or_a_positive_coefficient():
    from replay_probe import friction_coefficient
    levels = {'low': 0.2, 'medium': 0.5, 'high': 1.0}
    assert friction_coefficient('medium', levels) == 0.5
    assert friction_coefficient('5', levels) == 5.0
    for bad in ('0', '-1', 'nan', 'inf', 'sticky'):
        with pytest.raises(SystemExit, match='positive number'):
            friction_coefficient(bad, levels)
