"""Linearization of the one-step map (paper Eqs. 6-8) and its parameter derivatives (Sec. IV-D) against finite
differences; the matrix-free forward/adjoint kernels against the explicit matrices."""
from pathlib import Path

import numpy as np
import pytest

from flex_ident.identification.adjoint import adjoint_gradient, forward_sensitivities
from flex_ident.identification.feedback import lqr_tracking_feedback
from flex_ident.mechanics import variational_integrator as vi
from flex_ident.mechanics.assembly import build_model
from flex_ident.mechanics.examples import experiment_yaml
from flex_ident.mechanics.experiment import load_experiment
from flex_ident.mechanics.linearization import adjoint_gradient_along, forward_sensitivities_along, linearize
from flex_ident.mechanics.static_equilibrium import static_equilibrium

import flex_ident

BAXTER_URDF = Path(flex_ident.__file__).parent / 'data' / 'baxter_right_arm.urdf'


@pytest.fixture(scope='module')
def moving(tmp_path_factory):
    """Baxter + 6-link loop, deformed start, driven off its equilibrium with feedback, 2 substeps per sample."""
    path = experiment_yaml(tmp_path_factory.mktemp('lin') / 'exp.yaml', BAXTER_URDF, n_links=6,
                           clamp_xyz=(0.62, -0.78, -0.27))
    model = build_model(load_experiment(path), {'k_theta': 4.0, 'k_phi': 2.0})
    coef = model.coef_values()
    q_guess = np.zeros(model.n)
    q_guess[:7] = [0.0, -0.55, 0.0, 0.75, 0.0, 1.26, 0.0]
    eq = static_equilibrium(model, coef, q_guess)
    rng = np.random.default_rng(4)
    steps, S, dt = 25, 2, 0.01
    tau = eq.holding_torque + 0.5 * rng.normal(size=(steps, 7))
    theta = eq.q[:7] + 0.02 * rng.normal(size=(steps + 1, 7))
    fb = lqr_tracking_feedback(model, coef, eq.q, dt)
    traj = vi.simulate(model, coef, dt, eq.q, vi.rest_momentum(model, coef, dt / S, eq.q, tau[0]), tau, theta, fb,
                       substeps=S)
    return model, coef, traj, tau, theta, fb


def test_one_step_map_derivatives_match_finite_differences(moving):
    model, coef, traj, tau, theta, fb = moving
    lin = linearize(model, traj)
    n, k = model.n, 13
    x = traj.x[k]

    def step(x, c=coef, du=0.0):
        t = vi.simulate(model, c, traj.dt, x[:n], x[n:], tau[k:k + 1] + du, theta[k:k + 2], fb,
                        substeps=traj.substeps)
        return t.x[1]

    np.testing.assert_allclose(step(x), traj.x[k + 1], atol=1e-12)
    eps = 1e-6

    def fd(f, dim):
        return np.stack([(f(eps * e) - f(-eps * e)) / (2 * eps) for e in np.eye(dim)], axis=1)

    A = fd(lambda d: step(x + d), 2 * n)
    P = fd(lambda d: step(x, coef + 100 * d), len(coef)) / 100      # coefficients and torques are O(1-10):
    B = fd(lambda d: step(x, coef, 100 * d), 7) / 100               # larger steps against Newton's tolerance
    for mine, ref in ((lin.A[k], A), (lin.P[k], P), (lin.B[k], B)):
        assert np.max(np.abs(mine - ref)) < 1e-6 * np.max(np.abs(ref))


def test_matrix_free_kernels_agree_with_the_explicit_linearization(moving):
    model, coef, traj, tau, theta, fb = moving
    lin = linearize(model, traj)
    free = np.array([model.coef_index('k_theta'), model.coef_index('k_phi'), model.coef_index('damping_right_e1')])
    rng = np.random.default_rng(5)
    S0 = rng.normal(size=(2 * model.n, len(free)))
    P = np.ascontiguousarray(lin.P[:, :, free])
    explicit = forward_sensitivities(lin.A, P, S0)
    matrix_free = forward_sensitivities_along(model, traj, free, S0)
    np.testing.assert_allclose(matrix_free, explicit, rtol=1e-9, atol=1e-12 * np.max(np.abs(explicit)))
    dl_dx = rng.normal(size=(traj.q.shape[0], 2 * model.n))
    g_explicit = adjoint_gradient(lin.A, P, S0, dl_dx)
    g_free = adjoint_gradient_along(model, traj, free, S0, dl_dx)
    np.testing.assert_allclose(g_free, g_explicit, rtol=1e-9)
    # and the adjoint equals the forward route: sum_k dl_k . S_k
    np.testing.assert_allclose(g_free, np.einsum('kx,kxc->c', dl_dx, explicit), rtol=1e-9)
