"""Experiment YAML (CONTRACTS.md section 2) -> validated dataclasses -> model; one clear error per problem."""
import math
from pathlib import Path

import numpy as np
import pytest

import flex_ident
from flex_ident.mechanics.assembly import build_model
from flex_ident.mechanics.experiment import ExperimentError, load_experiment
from flex_ident.mechanics.examples import experiment_yaml
from flex_ident.mechanics.static_equilibrium import static_equilibrium

BAXTER_URDF = Path(flex_ident.__file__).parent / 'data' / 'baxter_right_arm.urdf'
REPO = Path(__file__).resolve().parents[4]


def test_contract_example_loads_with_paths_relative_to_the_yaml():
    exp = load_experiment(REPO / 'bags' / 'example_loop12' / 'experiment.yaml')
    assert Path(exp.arm.urdf_path).is_file()
    assert exp.arm.joints[0] == 'right_s0' and exp.object.links == 12
    assert exp.object.link_length_m == pytest.approx(2 * 0.25 * math.sin(math.pi / 12))
    assert [p.name for p in exp.identify.parameters] == ['k_theta', 'k_phi']
    assert exp.identify.window_s is None
    assert exp.arm.gravity_mps2 == (0.0, 0.0, -9.81)
    model = build_model(exp)
    assert model.n == 31 and model.n_constraints == 12
    assert model.coord_names[7:9] == ['loop_left_theta_1', 'loop_left_phi_1']
    assert model.coef_values()[model.coef_index('k_theta')] == 1.0        # the initial guess
    assert model.coefficients[model.coef_index('damping_right_s0')].value == pytest.approx(0.7)


def test_arm_only_experiment(tmp_path):
    path = tmp_path / 'arm.yaml'
    path.write_text(f'arm:\n  urdf: {BAXTER_URDF}\n  base_link: base\n  tip_link: right_gripper\n'
                    '  joints: [right_s0, right_s1, right_e0, right_e1, right_w0, right_w1, right_w2]\n'
                    '  gravity: 9.80665\n'
                    'identify:\n  parameters:\n    damping_right_s0: {initial: 0.5, min: 0.0, max: 5.0}\n')
    exp = load_experiment(path)
    model = build_model(exp)
    assert exp.object is None and model.n == 7 and model.n_constraints == 0
    assert model.gravity[2] == pytest.approx(-9.80665)
    eq = static_equilibrium(model, model.coef_values(), np.zeros(7))
    assert eq.holding_torque.shape == (7,) and abs(eq.holding_torque[1]) > 10     # the shoulder holds the arm up


def good_yaml(tmp_path, **kw):
    return experiment_yaml(tmp_path / 'exp.yaml', BAXTER_URDF, **kw)


@pytest.mark.parametrize('old, new, message', [
    ('  links: 12', '  links: 7', 'even integer'),
    ('  radius: 0.25', '  radius: -0.25', 'must be positive'),
    ('  mass: 0.6', '  mass: heavy', 'expected a number'),
    ('k_theta: {initial: 1.0, min: 0.001, max: 1000.0}', 'k_theta: {initial: 2000.0, min: 0.001, max: 1000.0}',
     'outside its bounds'),
    ('k_phi: {initial: 1.0, min: 0.001, max: 1000.0}', 'k_phi: {initial: 1.0, min: 10.0, max: 1.0}',
     'is not below max'),
    ('  tip_link: right_gripper\n', '', 'missing "tip_link"'),
    ('  clamp: {', '  clamp_pose: {', 'object.clamp: missing'),
    ('right_w1, right_w2]', 'right_w1, right_w1]', 'more than once'),
    ('  type: loop', '  type: rope', 'supported object type'),
    ('  tube_radius: 0.02', '  tube_radius: 0.5', 'smaller than radius'),
    ('  urdf: ', '  urdf: missing_', 'does not exist'),
])
def test_inconsistent_yaml_is_refused(tmp_path, old, new, message):
    path = good_yaml(tmp_path)
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new))
    with pytest.raises(ExperimentError, match=message):
        load_experiment(path)


def test_window_and_cost_are_validated(tmp_path):
    path = good_yaml(tmp_path, window=(5.0, 2.0))
    with pytest.raises(ExperimentError, match='window'):
        load_experiment(path)
    path = good_yaml(tmp_path, extra='  cost: everything\n')
    with pytest.raises(ExperimentError, match='cost'):
        load_experiment(path)


@pytest.mark.parametrize('joints, message', [
    ('[right_s0, right_s1, right_e0, right_e1, right_w0, right_w1, right_w3]', 'are not joints of URDF'),
    ('[right_s0, right_s1, right_e0, right_e1, right_w0, right_w1]', 'missing from arm.joints'),
    ('[right_s0, right_s1, right_e0, right_e1, right_w0, right_w1, right_w2, right_endpoint]', 'fixed joints'),
])
def test_joint_list_must_match_the_chain(tmp_path, joints, message):
    path = good_yaml(tmp_path)
    path.write_text(path.read_text().replace(
        '[right_s0, right_s1, right_e0, right_e1, right_w0, right_w1, right_w2]', joints))
    with pytest.raises(ExperimentError, match=message):
        build_model(load_experiment(path))


def test_unknown_parameter_names_are_refused(tmp_path):
    path = good_yaml(tmp_path, parameters={'k_theta': (1.0, 0.1, 10.0), 'k_psi': (1.0, 0.1, 10.0)})
    with pytest.raises(ExperimentError, match=r"\['k_psi'\] are not parameters of this model"):
        build_model(load_experiment(path))
