"""The stabilizing feedback: finite-horizon LQR gains, and a stable measured-torque simulation with them."""
from pathlib import Path

import numpy as np
from scipy.linalg import solve_discrete_are

from flex_ident.identification.feedback import (FeedbackWeights, arm_error_dynamics, lqr_tracking_feedback,
                                                riccati_gains)
from flex_ident.mechanics import variational_integrator as vi
from flex_ident.mechanics.assembly import build_model
from flex_ident.mechanics.experiment import load_experiment
from flex_ident.mechanics.static_equilibrium import static_equilibrium

REPO = Path(__file__).resolve().parents[4]


def test_finite_horizon_riccati_reaches_the_stationary_lqr_gain():
    rng = np.random.default_rng(1)
    A = np.eye(4) + 0.05 * rng.normal(size=(4, 4))
    B = rng.normal(size=(4, 2))
    Q, R = np.diag([1.0, 2.0, 0.5, 1.0]), np.diag([0.1, 0.3])
    K = riccati_gains(np.repeat(A[None], 400, axis=0), np.repeat(B[None], 400, axis=0), Q, R)
    X = solve_discrete_are(A, B, Q, R)
    K_inf = np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
    np.testing.assert_allclose(K[0], K_inf, rtol=1e-8)
    assert not np.allclose(K[-1], K_inf)                                # the horizon's end differs


def test_gains_from_bryson_weights_stabilize_the_arm_error_dynamics():
    exp = load_experiment(REPO / 'bags' / 'example_loop12' / 'experiment.yaml')
    model = build_model(exp)
    q = np.zeros(model.n)
    q[:7] = [0.0, -0.64, 0.0, 0.9, 0.0, 1.31, 0.0]
    fb = lqr_tracking_feedback(model, model.coef_values(), q, 0.01, FeedbackWeights(0.005, 1.0))
    assert np.all(np.linalg.eigvalsh(0.5 * (fb.Kp + fb.Kp.T)) > 0)
    assert np.all(np.linalg.eigvalsh(0.5 * (fb.Kd + fb.Kd.T)) > 0)
    A, B = arm_error_dynamics(model, model.coef_values(), q, 0.01)
    closed = A - B @ np.hstack([fb.Kp, fb.Kd])
    assert np.max(np.abs(np.linalg.eigvals(closed))) < 1.0
    stiffer = lqr_tracking_feedback(model, model.coef_values(), q, 0.01, FeedbackWeights(0.001, 1.0))
    assert np.trace(stiffer.Kp) > 3 * np.trace(fb.Kp)


def test_feedback_keeps_the_simulation_on_the_measured_arm_path_despite_a_wrong_model():
    """Measured torques of the 5/3 N m/rad loop drive a model with k = 1: without feedback the arm drifts away,
    with it the arm stays within millimetres of the measurement and the deviation carries the stiffness error."""
    exp = load_experiment(REPO / 'bags' / 'example_loop6' / 'experiment.yaml')
    model = build_model(exp, {'k_theta': 1.0, 'k_phi': 1.0})
    truth = np.load(REPO / 'bags' / 'example_loop6' / 'truth.npz')
    theta, tau = truth['arm_position'].astype(float)[:500], truth['effort'].astype(float)[:500]
    coef = model.coef_values()
    q_guess = np.zeros(model.n)
    q_guess[:7] = theta[0]
    eq = static_equilibrium(model, coef, q_guess)
    tau_i = 0.5 * (tau[:-1] + tau[1:])
    p0 = vi.rest_momentum(model, coef, 0.01, eq.q, tau_i[0])
    fb = lqr_tracking_feedback(model, coef, eq.q, 0.01)
    held = vi.simulate(model, coef, 0.01, eq.q, p0, tau_i, theta, fb)
    err = np.max(np.abs(held.q[:, :7] - theta))
    assert 1e-3 < err < 0.05
    try:
        free = vi.simulate(model, coef, 0.01, eq.q, p0, tau_i)
        assert np.max(np.abs(free.q[:, :7] - theta)) > 5 * err
    except vi.SimulationError:
        pass                                                             # or it diverges altogether
