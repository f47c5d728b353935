"""The whole gradient of the identification cost (adjoint, paper Lemma 1) and the residual Jacobian (forward
sensitivities) against finite differences of the complete pipeline: static equilibrium -> measured-torque
simulation with feedback -> cost."""
from pathlib import Path

import numpy as np
import pytest

from flex_ident.identification.adjoint import initial_state_sensitivity
from flex_ident.identification.feedback import lqr_tracking_feedback
from flex_ident.identification.measurement import load_measurements
from flex_ident.identification.problem import IdentificationProblem
from flex_ident.mechanics.assembly import build_model
from flex_ident.mechanics.experiment import load_experiment
from flex_ident.mechanics.static_equilibrium import static_equilibrium
from flex_ident.mechanics.variational_integrator import rest_momentum

REPO = Path(__file__).resolve().parents[4]
FREE = ['k_theta', 'k_phi', 'damping_right_w0']


def make_problem(name, cost_kind, window=(0.0, 3.0), substeps=1):
    exp = load_experiment(REPO / 'bags' / name / 'experiment.yaml')
    model = build_model(exp)
    data, _ = load_measurements(REPO / 'bags' / name / 'bag', list(exp.arm.joints), window)
    q_guess = np.zeros(model.n)
    q_guess[:7] = data.theta[0]
    eq = static_equilibrium(model, model.coef_values(), q_guess)
    fb = lqr_tracking_feedback(model, model.coef_values(), eq.q, data.dt)
    return IdentificationProblem(model, data, FREE, [1e-3, 1e-3, 1e-3], [1e3, 1e3, 1e3], fb, substeps=substeps,
                                 cost_kind=cost_kind, max_substeps=substeps)      # fixed discretization for FD


@pytest.mark.parametrize('name, cost_kind, substeps', [('example_loop6', 'end_effector', 1),
                                                       ('example_loop6', 'joint_angles', 1),
                                                       ('example_loop12', 'end_effector', 2)])
def test_gradient_and_jacobian_match_finite_differences(name, cost_kind, substeps):
    problem = make_problem(name, cost_kind, window=(0.0, 3.0 if name == 'example_loop6' else 2.0),
                           substeps=substeps)
    p = np.array([3.0, 2.0, 0.9])
    ev = problem.evaluate(p, jacobian=True, gradient=True)
    assert ev.ok and ev.cost > 0
    fd_grad, fd_jac = [], []
    for i in range(len(p)):
        eps = 1e-5 * p[i]
        up, down = p.copy(), p.copy()
        up[i] += eps
        down[i] -= eps
        a, b = problem.evaluate(up), problem.evaluate(down)
        fd_grad.append((a.cost - b.cost) / (2 * eps))
        fd_jac.append((a.residual - b.residual).ravel() / (2 * eps))
    fd_grad, fd_jac = np.array(fd_grad), np.array(fd_jac).T
    assert np.max(np.abs(ev.gradient - fd_grad)) < 1e-6 * np.max(np.abs(fd_grad))
    assert np.max(np.abs(ev.jacobian - fd_jac)) < 1e-6 * np.max(np.abs(fd_jac))
    # adjoint (one backward pass) and forward sensitivities give the same gradient
    np.testing.assert_allclose(ev.gradient, 2 * ev.residual.ravel() @ ev.jacobian, rtol=1e-9)


def test_initial_state_sensitivity_matches_finite_differences():
    problem = make_problem('example_loop12', 'end_effector', window=(0.0, 1.0), substeps=2)
    model = problem.model
    h = problem.data.dt / 2
    u0 = problem.tau_interval[0]

    def x0(c):
        eq = static_equilibrium(model, c, problem._q_guess)
        return np.concatenate([eq.q, rest_momentum(model, c, h, eq.q, u0)]), eq

    coef = problem.coef(np.array([3.0, 2.0, 0.9]))
    x, eq = x0(coef)
    S0 = initial_state_sensitivity(model, coef, h, eq.q, u0, eq.dq_dcoef)
    scale = np.max(np.abs(S0[:, problem.free_idx[:2]]))
    for i in problem.free_idx[:2]:
        eps = 1e-4 * coef[i]
        up, down = coef.copy(), coef.copy()
        up[i] += eps
        down[i] -= eps
        fd = (x0(up)[0] - x0(down)[0]) / (2 * eps)
        assert np.max(np.abs(fd)) > 0
        assert np.max(np.abs(S0[:, i] - fd)) < 1e-6 * scale
