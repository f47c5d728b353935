"""DER energies: analytic gradients and Hessians against finite differences; reference frames."""
import numpy as np
import pytest

from rod_deploy.physics import der_energy as de
from rod_deploy.physics.reference_frames import (edge_tangents, initial_reference_frames, parallel_transport,
                                                 reference_twist, time_parallel_transport)


@pytest.fixture(scope='module')
def rod():
    rng = np.random.default_rng(3)
    N = 6
    x = np.c_[np.linspace(0, 1, N + 1), 0.15 * rng.standard_normal(N + 1), 0.15 * rng.standard_normal(N + 1)]
    q = np.zeros(4 * N + 3)
    q[de.node_dofs(N + 1)] = x
    q[4 * np.arange(N) + 3] = 0.3 * rng.standard_normal(N)
    d1, _ = initial_reference_frames(x)
    t, ln = edge_tangents(x)
    rest = ln * rng.uniform(0.8, 1.2, N)
    return dict(N=N, q=q, d1=d1, t=t, rest=rest, vor=0.5 * (rest[1:] + rest[:-1]),
                kappa_rest=0.2 * rng.standard_normal((N - 1, 2)))


def _energy(r, q, which):
    """Energy with frames carried from the base configuration by time-parallel transport."""
    t, _ = edge_tangents(de.positions(q))
    d1, d2 = time_parallel_transport(r['d1'], r['t'], t)
    if which == 'stretch':
        return de.stretching(q, r['rest'], 3.0)
    if which == 'bend':
        return de.bending(q, d1, d2, r['vor'], 1.3, r['kappa_rest'])
    return de.twisting(q, d1, d2, reference_twist(d1, t), r['vor'], 0.7, 0.1)


def _dense(r, H, which):
    n = len(r['q'])
    A = np.zeros((n, n))
    idx = de.stretching_dofs(r['N']) if which == 'stretch' else de.stencil_dofs(r['N'])
    for k in range(len(H)):
        A[np.ix_(idx[k], idx[k])] += H[k]
    return A


@pytest.mark.parametrize('which', ['stretch', 'bend', 'twist'])
def test_gradient_matches_central_differences(rod, which, finite_differences):
    q = rod['q']
    _, g, _ = _energy(rod, q, which)
    fd = finite_differences.gradient(lambda v: _energy(rod, v, which)[0], q, h=1e-6)
    assert np.max(np.abs(g - fd)) < 1e-7 * max(1.0, np.max(np.abs(g)))


@pytest.mark.parametrize('which', ['stretch', 'bend', 'twist'])
def test_hessian_matches_second_differences_of_the_energy(rod, which, finite_differences):
    q = rod['q']
    _, _, H = _energy(rod, q, which)
    A = _dense(rod, H, which)
    fd = finite_differences.hessian(lambda v: _energy(rod, v, which)[0], q, h=1e-4)
    assert np.allclose(A, A.T, atol=1e-10)
    assert np.max(np.abs(A - fd)) < 2e-5 * np.max(np.abs(A))


def test_energies_vanish_for_straight_untwisted_rod():
    N = 5
    x = np.c_[np.linspace(0, 2, N + 1), np.zeros(N + 1), np.zeros(N + 1)]
    q = np.zeros(4 * N + 3)
    q[de.node_dofs(N + 1)] = x
    d1, d2 = initial_reference_frames(x)
    t, ln = edge_tangents(x)
    vor = 0.5 * (ln[1:] + ln[:-1])
    assert de.stretching(q, ln, 1.0)[0] == pytest.approx(0.0, abs=1e-15)
    assert de.bending(q, d1, d2, vor, 1.0)[0] == pytest.approx(0.0, abs=1e-15)
    assert de.twisting(q, d1, d2, reference_twist(d1, t), vor, 1.0)[0] == pytest.approx(0.0, abs=1e-15)


def test_bending_of_a_circular_arc_matches_the_curvature():
    # nodes on a circle of radius R: kappa = 2 tan(phi/2) / l_voronoi -> 1/R as the mesh is refined
    R, N = 2.0, 400
    a = np.linspace(0, np.pi / 2, N + 1)
    x = np.c_[R * np.sin(a), np.zeros(N + 1), R * (1 - np.cos(a))]
    q = np.zeros(4 * N + 3)
    q[de.node_dofs(N + 1)] = x
    d1, d2 = initial_reference_frames(x, d1_first=(0, 1, 0))
    t, ln = edge_tangents(x)
    E, _, _ = de.bending(q, d1, d2, 0.5 * (ln[1:] + ln[:-1]), 1.0)
    arc = R * np.pi / 2
    covered = arc * (N - 1) / N                      # Voronoi regions of the N - 1 interior nodes
    assert E == pytest.approx(0.5 * covered / R ** 2, rel=1e-4)


def test_parallel_transport_is_a_rotation_taking_t1_to_t2():
    rng = np.random.default_rng(0)
    t1 = rng.standard_normal((20, 3))
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = rng.standard_normal((20, 3))
    t2 /= np.linalg.norm(t2, axis=1, keepdims=True)
    assert np.allclose(parallel_transport(t1, t1, t2), t2)
    u = rng.standard_normal((20, 3))
    v = parallel_transport(u, t1, t2)
    assert np.allclose(np.linalg.norm(v, axis=1), np.linalg.norm(u, axis=1))
    assert np.allclose(np.sum(v * t2, axis=1), np.sum(u * t1, axis=1))   # angles to the tangent kept


def test_reference_twist_of_a_helix_is_its_geometric_torsion_times_length():
    # space-parallel frames have zero reference twist; a rotated frame picks up exactly the rotation
    N = 50
    s = np.linspace(0, 4 * np.pi, N + 1)
    x = np.c_[np.cos(s), np.sin(s), 0.3 * s]
    d1, _ = initial_reference_frames(x)
    t, _ = edge_tangents(x)
    assert np.max(np.abs(reference_twist(d1, t))) < 1e-12


@pytest.fixture(scope='module')
def table_rod():
    """A bent, twisted rod with a natural curvature, some nodes pressed into the table; its frames transported to a
    perturbed configuration (the gradient is that of the energy with frames carried from the current state, exact
    at that state: the DER linearisation), and an older configuration for the friction's slip velocity."""
    from rod_deploy.physics.der_simulator import DiscreteElasticRod, RodParameters
    rng = np.random.default_rng(7)
    N, r = 7, 0.05
    x = np.c_[np.linspace(0, 1, N + 1), 0.1 * rng.standard_normal(N + 1), np.zeros(N + 1)]
    x[:, 2] = r + np.where(np.arange(N + 1) % 2 == 0, -0.3, 0.5) * r          # every other node in contact
    rod = DiscreteElasticRod(x, RodParameters(EI=0.8, EA=40.0, GJ=0.5, rho_A=1.0, radius=r, table=True,
                                              friction=0.6, friction_velocity=0.05, natural_curvature=(0.7, -0.4)),
                             theta=0.2 * rng.standard_normal(N))
    q_old = rod.state.q.copy()
    rod._commit(q_old + 0.01 * rng.standard_normal(rod.ndof), rod.state.u, 0.0)
    return rod, rod.state.q.copy(), q_old


def test_simulator_band_assembly_matches_finite_differences(table_rod, finite_differences):
    # the assembled gradient and band Hessian against central and second differences of the energy (frames carried
    # from the rod's state, as in a Newton iteration)
    rod, q, _ = table_rod
    E, g, H = rod.elastic(q)
    En = lambda v: rod.elastic(v, False)[0]  # noqa: E731
    fd_g = finite_differences.gradient(En, q, h=1e-6)
    assert np.max(np.abs(g - fd_g)) < 1e-7 * np.max(np.abs(g))
    A = H.to_dense()
    fd_H = finite_differences.hessian(En, q, h=1e-4)
    assert np.max(np.abs(A - fd_H)) < 2e-5 * np.max(np.abs(A))
    assert np.max(np.abs(A - A.T)) < 1e-10 * np.max(np.abs(A))


def test_contact_and_friction_stiffness_match_finite_differences(table_rod):
    rod, q, q_old = table_rod
    dt = 0.1
    Ec, f, Hc = rod.contact(q, q_old, dt)
    assert Ec > 0 and np.count_nonzero(f) > 0
    n, h = len(q), 1e-7
    I = np.eye(n)
    fd_K = -np.column_stack([(rod.contact(q + h * I[i], q_old, dt, False)[1]
                              - rod.contact(q - h * I[i], q_old, dt, False)[1]) / (2 * h) for i in range(n)])
    K = Hc.to_dense()
    assert np.max(np.abs(K - fd_K)) < 1e-6 * np.max(np.abs(K))
    fd_f = -np.array([(rod.contact(q + h * I[i], hessian=False)[0] - rod.contact(q - h * I[i], hessian=False)[0])
                      / (2 * h) for i in range(n)])                           # the normal force is -dE/dq
    assert np.max(np.abs(rod.contact(q, hessian=False)[1] - fd_f)) < 1e-6 * np.max(np.abs(fd_f))
    # friction opposes the slip velocity of every node in contact
    v = (q - q_old) / dt
    for i in np.flatnonzero(q[2::4] < rod.contact_radius):
        assert np.dot(f[4 * i:4 * i + 2], v[4 * i:4 * i + 2]) < 0
