"""Identification recovers known stiffness: from our own model's recordings and from the independent MuJoCo
simulator's example bag; Levenberg-Marquardt against the paper's steepest descent; uncertainty from curvature."""
from pathlib import Path

import numpy as np
import pytest

import flex_ident
from flex_ident.identification.feedback import lqr_tracking_feedback
from flex_ident.identification.measurement import load_measurements, uniform_grid
from flex_ident.identification.optimizers import canonical_method, optimize
from flex_ident.identification.problem import IdentificationProblem
from flex_ident.identification.report import parameter_covariance
from flex_ident.identification.synthetic import synthesize_recording
from flex_ident.mechanics.assembly import build_model
from flex_ident.mechanics.examples import experiment_yaml
from flex_ident.mechanics.experiment import load_experiment
from flex_ident.mechanics.static_equilibrium import static_equilibrium

REPO = Path(__file__).resolve().parents[4]
BAXTER_URDF = Path(flex_ident.__file__).parent / 'data' / 'baxter_right_arm.urdf'


def build_problem(model, data, substeps=1):
    q_guess = np.zeros(model.n)
    q_guess[:7] = data.theta[0]
    coef = model.coef_values()
    eq = static_equilibrium(model, coef, q_guess)
    fb = lqr_tracking_feedback(model, coef, eq.q, data.dt)
    return IdentificationProblem(model, data, ['k_theta', 'k_phi'], [1e-3, 1e-3], [1e3, 1e3], fb, substeps=substeps)


@pytest.fixture(scope='module')
def synthetic(tmp_path_factory):
    """8-link loop, deformed start, 4 s of motion recorded from our own model at k = (3, 1.5), small noise."""
    path = experiment_yaml(tmp_path_factory.mktemp('syn') / 'exp.yaml', BAXTER_URDF, n_links=8,
                           clamp_xyz=(0.62, -0.79, -0.27))
    model = build_model(load_experiment(path))
    truth = model.coef_values()
    truth[model.coef_index('k_theta')], truth[model.coef_index('k_phi')] = 3.0, 1.5
    rec = synthesize_recording(model, truth, np.array([0.0, -0.55, 0.0, 0.75, 0.0, 1.26, 0.0]), duration_s=4.0,
                               amplitude_rad=0.12, seed=3, angle_noise_rad=1e-4, torque_noise_nm=0.05)
    data = uniform_grid(rec.t_s, rec.position, rec.effort)
    return model, data


def test_lm_recovers_stiffness_from_our_own_model(synthetic):
    model, data = synthetic
    problem = build_problem(model, data, substeps=2)
    result = optimize(problem, np.array([1.0, 1.0]), 'lm')
    np.testing.assert_allclose(result.params, [3.0, 1.5], rtol=0.01)
    assert result.iterations <= 10 and result.converged
    J, r = np.asarray(result.evaluation.jacobian), np.ravel(result.evaluation.residual)
    std, corr = parameter_covariance(J, r)
    assert np.all(std > 0) and np.all(std < 0.05 * result.params)
    # independently: the Gauss-Newton covariance sigma^2 (J^T J)^-1, and the two springs separately identifiable
    cov = np.linalg.inv(J.T @ J) * (r @ r) / (len(r) - 2)
    np.testing.assert_allclose(std, np.sqrt(np.diag(cov)), rtol=1e-6)
    assert corr[0, 1] == pytest.approx(cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1]), abs=1e-9)
    assert abs(corr[0, 1]) < 0.95
    # the truth lies within a few standard deviations (these are lower bounds: residuals are time-correlated)
    assert np.all(np.abs(result.params - [3.0, 1.5]) < 0.01 * np.array([3.0, 1.5]))


@pytest.fixture(scope='module')
def example6():
    exp = load_experiment(REPO / 'bags' / 'example_loop6' / 'experiment.yaml')
    model = build_model(exp)
    data, _ = load_measurements(REPO / 'bags' / 'example_loop6' / 'bag', list(exp.arm.joints), (0.0, 6.0))
    return model, data


def test_lm_recovers_the_independent_simulators_stiffness_in_few_iterations(example6):
    model, data = example6
    problem = build_problem(model, data)
    result = optimize(problem, np.array([1.0, 1.0]), 'lm')
    np.testing.assert_allclose(result.params, [5.0, 3.0], rtol=0.02)
    assert result.iterations <= 10
    costs = [h['cost'] for h in result.history]
    assert all(b < a for a, b in zip(costs, costs[1:]))           # monotone decrease
    assert costs[-1] < 1e-3 * costs[0]


def test_paper_baseline_and_lbfgsb_are_slower_than_lm(example6):
    model, data = example6
    lm = optimize(build_problem(model, data), np.array([1.0, 1.0]), 'lm')
    sd = optimize(build_problem(model, data), np.array([1.0, 1.0]), 'steepest', max_iterations=lm.iterations)
    assert sd.evaluation.cost > 10 * lm.evaluation.cost               # same iteration budget, far from converged
    costs = [h['cost'] for h in sd.history]
    assert all(b <= a for a, b in zip(costs, costs[1:]))              # Armijo: every accepted step decreases J
    lb = optimize(build_problem(model, data), np.array([1.0, 1.0]), 'lbfgsb', max_iterations=40)
    np.testing.assert_allclose(lb.params, lm.params, rtol=0.02)


def test_bounds_are_respected(example6):
    model, data = example6
    problem = IdentificationProblem(model, data, ['k_theta', 'k_phi'], [0.5, 0.5], [2.0, 10.0],
                                    build_problem(model, data).feedback)
    result = optimize(problem, np.array([1.0, 1.0]), 'lm')
    assert result.params[0] == pytest.approx(2.0)                      # the truth (5) is outside: stops at the bound
    assert 0.5 <= result.params[1] <= 10.0


def test_method_names():
    assert canonical_method('LM') == 'lm' and canonical_method('adjoint') == 'lbfgsb'
    assert canonical_method('armijo') == 'steepest'
    with pytest.raises(ValueError, match='unknown optimization method'):
        canonical_method('newton-raphson')


def test_parameter_covariance_of_a_linear_fit():
    rng = np.random.default_rng(0)
    J = rng.normal(size=(500, 2))
    r = 0.1 * rng.normal(size=500)
    std, corr = parameter_covariance(J, r)
    expected = np.sqrt(np.diag(np.linalg.inv(J.T @ J)) * (r @ r) / 498)
    np.testing.assert_allclose(std, expected)
    assert corr[0, 0] == pytest.approx(1.0)


class _CollapsingTrustRegion:
    """Mimics a loop that moves chaotically far from the truth: near the start the sensitivities are 100 times
    the slope of the cost, and every simulation more than 1e-5 (in log-stiffness) away from the start fails; LM
    has to raise its damping until a tiny step succeeds. Residual r = log c - log c_true, cost |r|^2; truth (6, 9),
    start (1, 1)."""

    def __init__(self):
        from flex_ident.identification.problem import ParameterTransform
        self.transform = ParameterTransform(np.array([1e-3, 1e-3]), np.array([1e3, 1e3]))
        self.z_true = np.log([6.0, 9.0])

    def evaluate(self, params, jacobian=True):
        from flex_ident.identification.problem import Evaluation
        c = np.asarray(params, float)
        z = np.log(c)
        r = (z - self.z_true)[None, :]
        chaotic = np.max(np.abs(z)) < 0.5                      # the region around the start z = 0
        if chaotic and np.max(np.abs(z)) > 1e-5:
            return Evaluation(params=c, cost=np.inf, residual=np.full_like(r, np.nan), ok=False, failure='diverged')
        return Evaluation(params=c, cost=float(np.sum(r * r)), residual=r,
                          jacobian=np.diag((100.0 if chaotic else 1.0) / c))


def test_lm_does_not_call_a_collapsed_trust_region_convergence():
    """Regression: a tiny step accepted only after the damping grew was reported as 'converged' at the start
    (seen on a noisy, wide-motion 12-link recording); LM must scan for a better region instead."""
    result = optimize(_CollapsingTrustRegion(), np.array([1.0, 1.0]), 'lm')
    np.testing.assert_allclose(result.params, [6.0, 9.0], rtol=1e-4)
    assert result.converged


def test_hac_std_is_calibrated_for_time_correlated_residuals():
    """A linear fit with smooth regressors and AR(1) errors (rho 0.9, what a simulated trajectory makes of noise):
    over 300 noise draws the truth lies within +-2 HAC std in close to 95 % of them (about 0.89 measured: eight
    seconds of slow motion hold few independent cycles), while the curvature std sigma^2 (J^T J)^-1 covers about a
    third (it is a lower bound)."""
    from flex_ident.identification.report import hac_parameter_covariance
    rng = np.random.default_rng(4)
    T, m = 800, 2
    t = np.arange(T) / 100.0
    J = np.stack([np.column_stack([np.sin(0.7 * t + c), np.cos(1.3 * t - c)]) for c in range(m)], axis=1)
    J = J.reshape(T * m, 2)
    truth = np.array([1.0, -0.5])
    hits_hac, hits_curv, reps = np.zeros(2), np.zeros(2), 300
    for _ in range(reps):
        e = np.zeros((T, m))
        w = rng.normal(size=(T, m))
        for k in range(1, T):
            e[k] = 0.9 * e[k - 1] + w[k]
        y = J @ truth + e.ravel()
        est, *_ = np.linalg.lstsq(J, y, rcond=None)
        r = (y - J @ est).reshape(T, m)
        std_hac, _, lag = hac_parameter_covariance(J, r)
        std_curv, _ = parameter_covariance(J, r)
        hits_hac += np.abs(est - truth) <= 2 * std_hac
        hits_curv += np.abs(est - truth) <= 2 * std_curv
        assert lag > 5
    assert np.all((0.82 <= hits_hac / reps) & (hits_hac / reps <= 0.99)), hits_hac / reps
    assert np.all(hits_curv / reps < 0.6), hits_curv / reps
