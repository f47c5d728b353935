"""Static equilibrium of the loop with the arm held, its parameter sensitivity, and failure on unreachable clamps."""
from pathlib import Path

import numpy as np
import pytest

from flex_ident.mechanics import variational_integrator as vi
from flex_ident.mechanics.assembly import build_model
from flex_ident.mechanics.examples import hanging_loop_model
from flex_ident.mechanics.experiment import load_experiment
from flex_ident.mechanics.static_equilibrium import EquilibriumError, static_equilibrium

REPO = Path(__file__).resolve().parents[4]


@pytest.fixture(scope='module')
def example12():
    exp = load_experiment(REPO / 'bags' / 'example_loop12' / 'experiment.yaml')
    model = build_model(exp, {'k_theta': 5.0, 'k_phi': 3.0})
    truth = np.load(REPO / 'bags' / 'example_loop12' / 'truth.npz')
    q_guess = np.zeros(model.n)
    q_guess[:7] = truth['arm_position'][0]
    return model, truth, q_guess


def test_equilibrium_matches_the_independent_simulator_at_rest(example12):
    model, truth, q_guess = example12
    eq = static_equilibrium(model, model.coef_values(), q_guess)
    np.testing.assert_array_equal(eq.q[:7], q_guess[:7])               # the arm is held
    assert np.max(np.abs(vi.constraint_residual(model, eq.q))) < 1e-12
    assert np.max(np.abs(eq.q[7:] - truth['loop_position'][0])) < 1e-5
    # the holding torque is what the (noise-free) torque sensors read at rest
    np.testing.assert_allclose(eq.holding_torque, truth['effort'][0], atol=5e-3)


def twisted_loop():
    """12-link loop below a fixed grasp, clamp 8 cm off and twisted by 0.3 rad: both springs matter."""
    from flex_ident.mechanics.rigid_body import rot_z
    model = hanging_loop_model(12, clamp_offset_m=(0.05, -0.04, -0.05))
    twist = np.eye(4)
    twist[:3, :3] = rot_z(0.3)
    return model.with_weld_targets([w.target @ twist for w in model.welds])


@pytest.mark.parametrize('case', ['example_at_rest', 'twisted'])
def test_equilibrium_sensitivity_matches_finite_differences(example12, case):
    if case == 'twisted':
        model = twisted_loop()
        q_guess = np.zeros(model.n)
    else:
        model, _, q_guess = example12
    coef = model.coef_values()
    eq = static_equilibrium(model, coef, q_guess)
    scale = np.max(np.abs(eq.dq_dcoef))
    for name in ('k_theta', 'k_phi'):
        i = model.coef_index(name)
        eps = 1e-5 * coef[i]
        up, down = coef.copy(), coef.copy()
        up[i] += eps
        down[i] -= eps
        fd = (static_equilibrium(model, up, eq.q).q - static_equilibrium(model, down, eq.q).q) / (2 * eps)
        assert np.max(np.abs(fd - eq.dq_dcoef[:, i])) < 1e-6 * scale
        if case == 'twisted':
            assert np.max(np.abs(fd)) > 0.1 * scale                    # both springs shape the loop
        else:
            assert np.max(np.abs(eq.dq_dcoef[:7, i])) == 0.0          # the arm is held


def test_continuation_reaches_a_deformed_clamp_pose():
    """From the rest shape the welds are moved to a clamp 8 cm off and 0.3 rad twisted."""
    model = twisted_loop()
    eq = static_equilibrium(model, model.coef_values(), np.zeros(model.n))
    assert np.max(np.abs(vi.constraint_residual(model, eq.q))) < 1e-12
    assert np.max(np.abs(eq.q)) > 0.1


def test_unreachable_clamp_is_a_clear_error():
    model = hanging_loop_model(8, clamp_offset_m=(0.0, 0.0, -0.6))
    with pytest.raises(EquilibriumError, match='cannot be closed onto its clamp'):
        static_equilibrium(model, model.coef_values(), np.zeros(model.n))
