"""DER statics against closed forms: cantilever, hanging rod, the folded-loop height (Sec. 6.1)."""
import numpy as np
import pytest

from rod_deploy.physics.der_simulator import DiscreteElasticRod, RodParameters
from rod_deploy.planning.scaling import LOOP_HEIGHT_COEFFICIENT, LOOP_HEIGHT_COEFFICIENT_EQ16


def _straight(N, L=1.0, direction=(1.0, 0.0, 0.0)):
    s = np.linspace(0.0, L, N + 1)
    return s[:, None] * np.asarray(direction)[None, :]


def _clamped(rod):
    rod.clamp_node(0)
    rod.clamp_node(1)
    rod.clamp_theta(0)
    return rod


@pytest.mark.parametrize('N', [20, 40, 80])
def test_cantilever_small_deflection(N):
    # Euler-Bernoulli: tip deflection w L^4 / (8 EI); the two-node clamp acts half an edge in (L_eff = L - dl/2)
    w, L = 1e-4, 1.0
    rod = _clamped(DiscreteElasticRod(_straight(N, L), RodParameters(EI=1.0, EA=1e4, GJ=0.7, rho_A=1.0,
                                                                       gravity=(0, 0, -w))))
    assert rod.static_solve(tol=1e-13) < 1e-3 * w / N
    tip = -rod.nodes[-1, 2]
    L_eff = L - 0.5 * L / N
    assert tip == pytest.approx(w * L_eff ** 4 / 8.0, rel=2e-3)
    assert tip == pytest.approx(w * L ** 4 / 8.0, rel=2.5 / N)            # converges to the classical value
    # the clamp carries the weight
    R = rod.reaction_forces()
    assert R[rod.node_dof(0)][2] + R[rod.node_dof(1)][2] == pytest.approx(w * L, rel=1e-9)


def test_cantilever_tip_load_large_deflection_matches_elastica():
    # horizontal cantilever under a tip load P (no gravity); compare with the elastica by shooting
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq
    P, L, N = 2.0, 1.0, 100
    rod = _clamped(DiscreteElasticRod(_straight(N, L), RodParameters(EI=1.0, EA=1e7, GJ=0.7, rho_A=1.0,
                                                                       gravity=(0, 0, 0))))
    rod.gravity_force[rod.node_dof(-1)[2]] = -P
    rod.static_solve(tol=1e-11, max_iter=200, shift=1e-3)
    dl = L / N

    def tip_moment(m0, length):
        # theta' = m, m' = P cos(theta); m(length) = 0
        sol = solve_ivp(lambda s, y: [y[1], P * np.cos(y[0])], [0, length], [0.0, m0], rtol=1e-11, atol=1e-12)
        return sol.y[1, -1]

    length = L - dl / 2
    m0 = brentq(tip_moment, -5, 0.0, args=(length,))
    sol = solve_ivp(lambda s, y: [y[1], P * np.cos(y[0]), np.cos(y[0]), np.sin(y[0])], [0, length],
                    [0.0, m0, 0.0, 0.0], rtol=1e-11, atol=1e-12)
    x_tip, z_tip = sol.y[2, -1] + dl / 2, sol.y[3, -1]
    assert rod.nodes[-1, 0] == pytest.approx(x_tip, abs=2e-3)
    assert rod.nodes[-1, 2] == pytest.approx(z_tip, abs=2e-3)


def test_hanging_rod_stretches_under_its_own_weight():
    # vertical rod clamped at the top: elongation w L^2 / (2 EA) (first edge rigid in the clamp)
    N, L, w, EA = 50, 1.0, 1.0, 50.0
    rod = _clamped(DiscreteElasticRod(_straight(N, L, (0, 0, -1)), RodParameters(EI=1e-3, EA=EA, GJ=1e-3,
                                                                                   rho_A=w, gravity=(0, 0, -1))))
    assert rod.static_solve(tol=1e-12) < 1e-8
    dl = L / N
    # tension in edge j = weight below its midpoint (lumped masses), summed over the free edges
    expected = w * (L - dl) ** 2 / (2 * EA)
    assert -rod.nodes[-1, 2] - L == pytest.approx(expected, rel=2e-2)
    assert np.allclose(rod.nodes[:, :2], 0.0, atol=1e-12)


@pytest.mark.parametrize('dl', [0.1, 0.05])
def test_folded_loop_height_recovers_0_9066(dl):
    """A rod folded back over itself on the table (paper Fig. 8a): h_f = 0.9066 (k_b/(rho A g))^(1/3).

    Dimensionless DER (EI = 1, rho A g = 1/2, i.e. lengths in the L_gb of Eq. 16), frictionless table contact,
    started from a circular loop; the equilibrium loop height is 1.1422 L_gb = 0.9066 x 2^(1/3) L_gb.
    """
    r = 0.002
    C = 6.0
    R = C / (2 * np.pi)
    low = np.c_[np.arange(-6, 0, dl), np.zeros(int(round(6 / dl))), np.full(int(round(6 / dl)), r)]
    phi = np.arange(0, 2 * np.pi, dl / R)
    circ = np.c_[R * np.sin(phi), 0 * phi, r + R * (1 - np.cos(phi))]
    s_up = np.arange(0, 6, dl)
    up = np.c_[-s_up, 0 * s_up, 0 * s_up + r]
    rod = DiscreteElasticRod(np.r_[low, circ, up], RodParameters.dimensionless(1e4, radius=r, table=True))
    rod.fixed[rod.node_dof(0)[0]] = True      # the loop may roll (neutral mode): pin one end in x
    rod.fixed[1::4] = True                    # planar
    rod.fixed[3::4] = True
    assert rod.static_solve(tol=1e-8, max_iter=400, shift=1e-3) < 1e-7
    h = rod.nodes[:, 2].max() - r
    assert h == pytest.approx(LOOP_HEIGHT_COEFFICIENT_EQ16, rel=0.015)
    assert h / 2 ** (1 / 3) == pytest.approx(LOOP_HEIGHT_COEFFICIENT, rel=0.015)
