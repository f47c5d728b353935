"""DER with a natural (rest) curvature: a free rod relaxes to a circular arc of that radius; the simulator's
elastic forces are the gradient of its energy (finite differences)."""
import numpy as np
import pytest

from rod_deploy.physics.der_simulator import DiscreteElasticRod, RodParameters


def _clamped_straight(N, L, natural_curvature):
    x = np.c_[np.linspace(0.0, L, N + 1), np.zeros(N + 1), np.zeros(N + 1)]
    rod = DiscreteElasticRod(x, RodParameters(EI=1.0, EA=1e5, GJ=0.7, rho_A=1.0, gravity=(0, 0, 0),
                                              natural_curvature=natural_curvature), d1_first=(0, 0, 1))
    rod.clamp_node(0)
    rod.clamp_node(1)
    rod.clamp_theta(0)
    return rod


def _circle_fit(p):
    """Centre and radius of the least-squares circle through planar points p (k, 2)."""
    A = np.c_[2 * p, np.ones(len(p))]
    c = np.linalg.lstsq(A, np.sum(p ** 2, axis=1), rcond=None)[0]
    return c[:2], float(np.sqrt(c[2] + c[:2] @ c[:2]))


@pytest.mark.parametrize('component', [0, 1])
@pytest.mark.parametrize('N', [40, 80])
def test_a_free_rod_with_natural_curvature_lies_on_a_circle_of_that_radius(N, component):
    L, k0 = 1.0, 4.0                       # 229 degrees of arc
    kappa = [0.0, 0.0]
    kappa[component] = k0
    rod = _clamped_straight(N, L, tuple(kappa))
    assert rod.static_solve(tol=1e-10, max_iter=200, shift=1e-3) < 1e-8
    x = rod.nodes
    # planar, normal to kb: kappa1 = kb . d2 bends towards d1 = z (normal y), kappa2 = -kb . d1 towards d2 (normal z)
    normal_axis = 1 if component == 0 else 2
    assert np.max(np.abs(x[:, normal_axis])) < 1e-8
    plane = x[:, [0, 2 if component == 0 else 1]]
    centre, radius = _circle_fit(plane)
    # the discrete rest shape is a polygon with turning angle k0 dl inscribed in a circle of radius
    # dl / (2 sin(k0 dl / 2)) = (1 / k0) (1 + (k0 dl)^2 / 24 + ...)
    dl = L / N
    assert radius == pytest.approx(dl / (2 * np.sin(k0 * dl / 2)), rel=1e-6)
    assert radius == pytest.approx(1 / k0, rel=(k0 * dl) ** 2 / 10)
    assert np.max(np.abs(np.linalg.norm(plane - centre, axis=1) - radius)) < 1e-8
    assert rod.energies()['elastic'] < 1e-12                    # the arc is the stress-free state
    # a straight rod has no rest curvature: it stays straight
    straight = _clamped_straight(N, L, (0.0, 0.0))
    straight.static_solve(tol=1e-10)
    assert np.max(np.abs(straight.nodes[:, 1:])) < 1e-12


def test_elastic_forces_and_hessian_match_finite_differences_of_the_energy_with_natural_curvature(finite_differences):
    rng = np.random.default_rng(5)
    N = 6
    x = np.c_[np.linspace(0, 0.4, N + 1), 0.02 * rng.standard_normal(N + 1), 0.02 * rng.standard_normal(N + 1)]
    rod = DiscreteElasticRod(x, RodParameters(EI=0.3, EA=50.0, GJ=0.2, rho_A=1.0, natural_curvature=(2.0, -3.0)))
    q = rod.state.q.copy()
    assert rod.elastic(q, hessian=False)[0] > 1e-3               # curved rest state: the straight-ish rod is loaded
    E = lambda v: rod.elastic(v, hessian=False)[0]  # noqa: E731
    _, g, H = rod.elastic(q)
    fd = finite_differences.gradient(E, q, h=1e-6)
    assert np.max(np.abs(g - fd)) < 1e-6 * np.max(np.abs(g))
    A = H.to_dense()
    fd2 = finite_differences.hessian(E, q, h=1e-4)
    assert np.max(np.abs(A - fd2)) < 2e-5 * np.max(np.abs(A))


def test_the_rod_files_natural_curvature_turns_a_laid_rod_left():
    """natural_curvature > 0 (rod YAML) turns left seen from above, for a rod laid as the planner lays it
    (material director d1 vertical on the table; no gravity here, so the arc is the rest shape)."""
    import dataclasses

    from rod_deploy.deployment.simulate import material_parameters
    from rod_deploy.planning.rod_description import RodDescriptionError, rod_description_from_dict
    rod = rod_description_from_dict({'length': 0.3, 'radius': 0.002, 'L_gb': 0.034, 'natural_curvature': 5.0})
    assert rod.natural_curvature_per_m == 5.0
    with pytest.raises(RodDescriptionError, match='"natural_curvature" must be finite'):
        rod_description_from_dict({'length': 0.3, 'radius': 0.002, 'L_gb': 0.034, 'natural_curvature': 'nan'})
    for k0 in (5.0, -5.0):
        curved = dataclasses.replace(rod, natural_curvature_per_m=k0)
        params = dataclasses.replace(material_parameters(curved, 0.5, 0.0), gravity=(0.0, 0.0, 0.0), table=False)
        x = np.c_[np.linspace(0.0, 0.3, 31), np.zeros(31), np.zeros(31)]
        r = DiscreteElasticRod(x, params, d1_first=(0, 0, 1))
        r.clamp_node(0)
        r.clamp_node(1)
        r.clamp_theta(0)
        r.static_solve(tol=1e-12, max_iter=200, shift=1e-3)
        y_end = r.nodes[-1, 1]
        assert np.sign(y_end) == np.sign(k0) and abs(y_end) > 0.05          # a 0.3 m arc of radius 0.2 m
        assert np.max(np.abs(r.nodes[:, 2])) < 1e-9                        # in the table's plane
