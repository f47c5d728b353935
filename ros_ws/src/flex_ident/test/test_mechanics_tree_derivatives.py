"""The tree recursions against finite differences, and the contract loop's exact geometry."""
import math
from pathlib import Path

import numpy as np
import pytest

import flex_ident
from flex_ident.mechanics import tree_kinematics as tk
from flex_ident.mechanics.assembly import build_model
from flex_ident.mechanics.examples import experiment_yaml
from flex_ident.mechanics.experiment import load_experiment
from flex_ident.mechanics.loop_geometry import rest_shape_vertices
from flex_ident.mechanics.model import Coefficient, ConstantForce, CoulombFriction
from flex_ident.mechanics.rigid_body import roty, trans
from flex_ident.mechanics.variational_integrator import constraint_jacobian, constraint_residual

BAXTER_URDF = Path(flex_ident.__file__).parent / 'data' / 'baxter_right_arm.urdf'
EPS = 1e-6


@pytest.fixture(scope='module')
def model(tmp_path_factory):
    path = experiment_yaml(tmp_path_factory.mktemp('exp') / 'exp.yaml', BAXTER_URDF, n_links=12)
    return build_model(load_experiment(path), {'k_theta': 4.0, 'k_phi': 2.5})


def lagrangian(model, q, v, coef):
    n, nc = model.n, len(coef)
    out = [np.zeros(n), np.zeros(n), np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, nc))]
    T, V = tk.lagrangian_derivatives(model.kernel(), q, v, coef, True, *out)
    return (T - V, *out)


def central(f, x, eps=EPS):
    cols = []
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = eps
        cols.append((np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * eps))
    return np.stack(cols, axis=-1)


def rel_err(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-12)


def test_lagrangian_derivatives_match_finite_differences(model):
    rng = np.random.default_rng(0)
    q, v = 0.4 * rng.normal(size=model.n), rng.normal(size=model.n)
    coef = model.coef_values()
    L, Lq, Lv, Lqq, Lqv, Lvv, dLq_dc = lagrangian(model, q, v, coef)
    assert rel_err(Lq, central(lambda x: lagrangian(model, x, v, coef)[0], q)) < 1e-6
    assert rel_err(Lv, central(lambda x: lagrangian(model, q, x, coef)[0], v)) < 1e-6
    assert rel_err(Lqq, central(lambda x: lagrangian(model, x, v, coef)[1], q)) < 1e-6
    assert rel_err(Lqv, central(lambda x: lagrangian(model, q, x, coef)[1], v)) < 1e-6
    assert rel_err(Lvv, central(lambda x: lagrangian(model, q, x, coef)[2], v)) < 1e-6
    assert rel_err(Lqv.T, central(lambda x: lagrangian(model, x, v, coef)[2], q)) < 1e-6
    assert rel_err(dLq_dc, central(lambda c: lagrangian(model, q, v, c)[1], coef)) < 1e-6
    assert 0.5 * v @ Lvv @ v == pytest.approx(tk.lagrangian_derivatives(
        model.kernel(), q, v, coef, False, np.zeros(model.n), np.zeros(model.n), np.zeros((1, 1)), np.zeros((1, 1)),
        np.zeros((1, 1)), np.zeros((model.n, len(coef))))[0], rel=1e-12)


def test_weld_constraint_derivatives_match_finite_differences(model):
    rng = np.random.default_rng(1)
    q = 0.4 * rng.normal(size=model.n)
    m = model.n_constraints
    lam = rng.normal(size=m)

    def welds(x):
        h, Dh, H = np.zeros(m), np.zeros((m, model.n)), np.zeros((model.n, model.n))
        tk.weld_constraints(model.kernel(), x, lam, True, h, Dh, H)
        return h, Dh, H

    h, Dh, H = welds(q)
    assert rel_err(Dh, central(lambda x: welds(x)[0], q)) < 1e-6
    assert rel_err(H, central(lambda x: lam @ welds(x)[1], q)) < 1e-6


def test_generalized_force_derivatives_match_finite_differences(model):
    """Inputs with a gain coefficient, tracking feedback, viscous damping, Coulomb friction, constant force."""
    nc0 = len(model.coefficients)
    m2 = model.extended([Coefficient('coulomb', 0.3, 'test', 'N m'), Coefficient('bias', -0.2, 'test', 'N m'),
                         Coefficient('gain', 1.1, 'test')],
                        [CoulombFriction(2, nc0, 0.05), ConstantForce(5, nc0 + 1)])
    m2.input_gain_coef = model.input_gain_coef.copy()
    m2.input_gain_coef[3] = nc0 + 2
    na = len(model.measured_coords)
    rng = np.random.default_rng(2)
    km = m2.kernel()._replace(fb_Kp=np.diag(rng.uniform(10, 50, na)) + 0.1, fb_Kd=np.diag(rng.uniform(1, 5, na)))
    n, nu, nc = m2.n, len(m2.input_coords), len(m2.coefficients)
    q, v = 0.3 * rng.normal(size=n), rng.normal(size=n)
    u = rng.normal(size=nu + 2 * na)
    coef = m2.coef_values()

    def forces(q, v, u, c):
        out = [np.zeros(n), np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, len(u))), np.zeros((n, nc))]
        tk.generalized_forces(km, q, v, u, c, *out)
        return out

    F, dF_dq, dF_dv, dF_du, dF_dc = forces(q, v, u, coef)
    np.testing.assert_allclose(dF_dq, central(lambda x: forces(x, v, u, coef)[0], q), atol=1e-7)
    np.testing.assert_allclose(dF_dv, central(lambda x: forces(q, x, u, coef)[0], v), atol=1e-7)
    np.testing.assert_allclose(dF_du, central(lambda x: forces(q, v, x, coef)[0], u), atol=1e-7)
    np.testing.assert_allclose(dF_dc, central(lambda x: forces(q, v, u, x)[0], coef), atol=1e-7)
    assert np.max(np.abs(dF_dc[:, nc0:])) > 0                          # the added effects act


@pytest.mark.parametrize('n_links', [6, 12])
def test_rest_shape_closes_the_loop_with_full_rank_welds(tmp_path, n_links):
    """G = C T(0, 0, -2R) with the same orientation: the undeformed loop satisfies all 12 constraints."""
    exp = load_experiment(experiment_yaml(tmp_path / 'exp.yaml', BAXTER_URDF, n_links=n_links))
    model = build_model(exp)
    km = model.kernel()
    q = np.zeros(model.n)
    q[:7] = [0.0, -0.55, 0.0, 0.75, 0.0, 1.26, 0.0]
    coord, off = model.frames['ee']
    R, p = tk.frame_pose(km, q, coord, np.ascontiguousarray(off[:3, :3]), np.ascontiguousarray(off[:3, 3]))
    G = np.eye(4)
    G[:3, :3], G[:3, 3] = R, p
    C = G @ trans(0, 0, 2 * 0.25)
    N = n_links
    closed = model.with_weld_targets([C @ roty(math.pi / N - math.pi), C @ roty(-math.pi / N)])
    assert np.max(np.abs(constraint_residual(closed, q))) < 1e-14
    Dh = constraint_jacobian(closed, q)
    assert Dh.shape == (12, 7 + 2 * N) and np.linalg.matrix_rank(Dh) == 12
    # every link starts at the contract's vertex: left branch vertices 0..N/2, right branch 0, -1, ..., -N/2
    verts = rest_shape_vertices(N, 0.25)
    for side, sign in (('left', 1), ('right', -1)):
        for k in range(1, N // 2 + 1):
            c = model.coord_names.index(f'loop_{side}_phi_{k}')
            _, pk = tk.frame_pose(km, q, c, np.eye(3), np.zeros(3))
            expected = G @ np.append(verts[(sign * (k - 1)) % N], 1.0)
            np.testing.assert_allclose(pk, expected[:3], atol=1e-14)
