"""Midpoint variational integrator: constraints, energy, order, and agreement with independent simulators."""
from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.linalg import null_space

from flex_ident.mechanics import variational_integrator as vi
from flex_ident.mechanics.assembly import add_serial_arm, build_model
from flex_ident.mechanics.examples import hanging_loop_model, spatial_arm_urdf
from flex_ident.mechanics.experiment import load_experiment
from flex_ident.mechanics.model import ModelBuilder
from flex_ident.mechanics.static_equilibrium import static_equilibrium
from flex_ident.mechanics.urdf import load_urdf, serial_chain
from flex_ident.identification.feedback import lqr_tracking_feedback

REPO = Path(__file__).resolve().parents[4]


@pytest.fixture(scope='module')
def loop8():
    """The contract loop (8 links, 16 coordinates, 12 welds) hanging from a fixed grasp, clamp displaced."""
    model = hanging_loop_model(8, clamp_offset_m=(0.03, 0.02, -0.04))
    coef = model.coef_values()
    eq = static_equilibrium(model, coef, np.zeros(model.n))
    Z = null_space(vi.constraint_jacobian(model, eq.q))
    v0 = Z @ np.random.default_rng(0).normal(size=Z.shape[1])
    v0 *= np.sqrt(0.02 / vi.energy(model, coef, eq.q, v0)[0])      # 20 mJ of kinetic energy
    return model, coef, eq, v0


def test_constraints_hold_to_1e10_at_every_step(loop8):
    model, coef, eq, v0 = loop8
    traj = vi.simulate(model, coef, 0.01, eq.q, vi.continuous_momentum(model, coef, eq.q, v0),
                       np.zeros((500, 0)))
    h = np.array([vi.constraint_residual(model, q) for q in traj.q_fine])
    assert np.max(np.abs(h)) < 1e-10
    assert np.ptp(traj.q, axis=0).max() > 0.01       # it really moved
    assert np.max(traj.newton_iterations) <= 6


def test_energy_error_stays_bounded_over_10000_steps(loop8):
    """Conservative system (springs, gravity, welds, no damping): the midpoint VI's energy error oscillates
    without drift."""
    model, coef, eq, v0 = loop8
    dt = 0.01
    traj = vi.simulate(model, coef, dt, eq.q, vi.continuous_momentum(model, coef, eq.q, v0),
                       np.zeros((10000, 0)))
    assert np.max(np.abs(traj.q - eq.q)) > 0.02
    E = vi.midpoint_energies(model, coef, traj.q_fine, dt)
    kinetic = vi.energy(model, coef, eq.q, v0)[0]
    deviation = np.abs(E - E[0])
    assert deviation.max() < 0.05 * kinetic          # omega dt ~ 1 for the stiffest loop modes at dt = 10 ms
    # no drift: the last thousand steps are no worse than the first thousand (within 20 %)
    assert deviation[-1000:].max() < 1.2 * deviation[:1000].max() + 1e-12


def test_second_order_convergence_in_dt(loop8):
    model, coef, eq, v0 = loop8
    p0 = vi.continuous_momentum(model, coef, eq.q, v0)
    T = 0.5
    ref = vi.simulate(model, coef, T / 3200, eq.q, vi.continuous_momentum(model, coef, eq.q, v0),
                      np.zeros((3200, 0))).q[-1]
    errors = [np.max(np.abs(vi.simulate(model, coef, T / N, eq.q, p0, np.zeros((N, 0))).q[-1] - ref))
              for N in (100, 200, 400)]
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(ratios > 3.5) and np.all(ratios < 4.6), (errors, ratios)


def test_spatial_arm_agrees_with_mujoco(tmp_path):
    """Independent simulator: MuJoCo (RK4, 0.1 ms) on the same URDF, driven by the same torques."""
    path = spatial_arm_urdf(tmp_path / 'arm.urdf', damping=0.3)
    chain = serial_chain(load_urdf(path), 'base', 'tip')
    builder = ModelBuilder()
    add_serial_arm(builder, chain, ['j1', 'j2', 'j3'])
    model = builder.build()
    coef = model.coef_values()
    mj = mujoco.MjModel.from_xml_path(str(path))
    mj.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    mj.opt.timestep = 1e-4
    data = mujoco.MjData(mj)
    q0, v0 = np.array([0.3, -0.5, 0.8]), np.array([0.5, -1.0, 2.0])
    data.qpos[:], data.qvel[:] = q0, v0

    def tau(t):
        return np.array([2 * np.sin(3 * t), 5 * np.cos(2 * t), 0.5 * np.sin(5 * t)])

    dt, T = 0.002, 1.0
    steps = int(round(T / dt))
    per = int(round(dt / mj.opt.timestep))
    for k in range(steps):
        data.qfrc_applied[:] = tau((k + 0.5) * dt)           # same piecewise-constant torque as the VI step
        for _ in range(per):
            mujoco.mj_step(mj, data)
    U = np.array([tau((k + 0.5) * dt) for k in range(steps)])
    traj = vi.simulate(model, coef, dt, q0, vi.continuous_momentum(model, coef, q0, v0), U)
    assert np.ptp(traj.q, axis=0).min() > 0.3
    assert np.max(np.abs(traj.q[-1] - data.qpos)) < 1e-4


@pytest.mark.parametrize('name', ['example_loop6'])
def test_closed_loop_agrees_with_the_independent_mujoco_loop_simulator(name):
    """The example recording's noise-free truth (bags/<name>/truth.npz, MuJoCo, soft welds, RK4 at 1 ms): driven by
    its efforts and held to its arm angles, our model reproduces its loop angles."""
    exp = load_experiment(REPO / 'bags' / name / 'experiment.yaml')
    model = build_model(exp, {'k_theta': 5.0, 'k_phi': 3.0})
    truth = np.load(REPO / 'bags' / name / 'truth.npz')
    theta, tau = truth['arm_position'].astype(float), truth['effort'].astype(float)
    loop = truth['loop_position'].astype(float)
    coef = model.coef_values()
    q_guess = np.zeros(model.n)
    q_guess[:7] = theta[0]
    eq = static_equilibrium(model, coef, q_guess)
    assert np.max(np.abs(eq.q[7:] - loop[0])) < 1e-5
    S = 2
    tau_interval = 0.5 * (tau[:-1] + tau[1:])
    traj = vi.simulate(model, coef, 0.01, eq.q, vi.rest_momentum(model, coef, 0.01 / S, eq.q, tau_interval[0]),
                       tau_interval, theta, lqr_tracking_feedback(model, coef, eq.q, 0.01), substeps=S)
    assert np.ptp(loop, axis=0).max() > 0.1
    assert np.max(np.abs(traj.q[:, 7:] - loop)) < 2e-3
    assert np.max(np.abs(traj.q[:, :7] - theta)) < 2e-4


def _accepted_step_error_rad(model, coef, q, mu, dt):
    """Largest configuration error one VI step may keep: Newton accepts q_{k+1} once the DEL residual is below
    DEL_TOLERANCE * scale (momentum units, scale = max(1, |p_k|) = 1 at rest), and near rest that residual is
    dominated by the kinetic term M(q) (q_{k+1} - q_k^exact) / dt. On the constraint manifold (tangent basis Z of
    the welds) an error e leaves a residual of at least m_min |e| / dt, so |e| <= dt * DEL_TOLERANCE / m_min, with
    m_min the smallest eigenvalue of the mass matrix restricted to the manifold."""
    from flex_ident.mechanics.tree_kinematics import lagrangian_derivatives
    n, nc = model.n, len(coef)
    Lvv = np.zeros((n, n))
    lagrangian_derivatives(model.kernel(), q, np.zeros(n), coef, True, np.zeros(n), np.zeros(n), np.zeros((n, n)),
                           np.zeros((n, n)), Lvv, np.zeros((n, nc)))
    Z = null_space(vi.constraint_jacobian(model, q))
    m_min = np.linalg.eigvalsh(Z.T @ Lvv @ Z).min()
    return dt * vi.DEL_TOLERANCE / m_min


def test_equilibrium_start_stays_at_rest():
    """A start at the static equilibrium with the rest momentum stays there to the integrator's own tolerance.

    Root cause of the machine dependence this bound replaces (a fixed 1e-9 failed with some OpenBLAS kernels): the
    equilibrium itself is exact to about 1e-16 on every kernel; at rest Newton accepts the extrapolated guess
    without iterating, the cubic extrapolation grows the round-off (kernel dependent) polynomially, and once the
    DEL residual passes DEL_TOLERANCE one Newton correction lands anywhere within the accepted error
    dt * DEL_TOLERANCE / m_min (1.7e-9 rad for this loop). The drift over N steps is therefore bounded by
    N times that (triangle inequality), and a start off equilibrium by 1e-4 rad moves far more."""
    model = hanging_loop_model(10, clamp_offset_m=(0.0, 0.03, -0.05))
    coef = model.coef_values()
    eq = static_equilibrium(model, coef, np.zeros(model.n))
    dt, steps = 0.01, 300
    per_step = _accepted_step_error_rad(model, coef, eq.q, eq.mu, dt)
    assert 1e-10 < per_step < 1e-7                    # the mechanism's scale for this light loop
    bound = steps * per_step

    def drift(q0):
        traj = vi.simulate(model, coef, dt, q0, vi.rest_momentum(model, coef, dt, q0, np.zeros(0)),
                           np.zeros((steps, 0)))
        return np.max(np.abs(traj.q - eq.q))

    assert drift(eq.q) < bound
    # the bound discriminates: a start 1e-4 rad off the equilibrium (along the constraint manifold) moves much more
    Z = null_space(vi.constraint_jacobian(model, eq.q))
    assert drift(eq.q + 1e-4 * Z[:, 0] / np.abs(Z[:, 0]).max()) > 10 * bound


def test_substeps_follow_the_weld_tension_of_the_motion():
    """The welds' curvature stiffness is integrated at the node (explicitly): the 12-link example at 10 ms needs
    2 substeps once the motion tensions the loop; required_substeps finds that from the multipliers, and with one
    substep a period-2 oscillation grows (the full recording then diverges at about 5.7 s)."""
    exp = load_experiment(REPO / 'bags' / 'example_loop12' / 'experiment.yaml')
    model = build_model(exp, {'k_theta': 5.0, 'k_phi': 3.0})
    truth = np.load(REPO / 'bags' / 'example_loop12' / 'truth.npz')
    theta, tau = truth['arm_position'].astype(float)[:401], truth['effort'].astype(float)[:401]
    coef = model.coef_values()
    q_guess = np.zeros(model.n)
    q_guess[:7] = theta[0]
    eq = static_equilibrium(model, coef, q_guess)
    assert vi.stable_substeps(model, coef, 0.01, eq.q, eq.mu) == 1      # at rest, the loop is barely tensioned
    feedback = lqr_tracking_feedback(model, coef, eq.q, 0.01)
    tau_interval = 0.5 * (tau[:-1] + tau[1:])

    def run(S):
        return vi.simulate(model, coef, 0.01, eq.q, vi.rest_momentum(model, coef, 0.01 / S, eq.q, tau_interval[0]),
                           tau_interval, theta, feedback, substeps=S)

    loop = truth['loop_position'].astype(float)[:401]
    coarse, fine = run(1), run(2)
    assert vi.required_substeps(model, coarse, safety=1.0) >= 2
    assert vi.required_substeps(model, fine, safety=1.0) == 2
    assert np.max(np.abs(fine.q[:, 7:] - loop)) < 1e-3                 # stable: matches the MuJoCo truth
    assert np.max(np.abs(coarse.q[:, 7:] - loop)) > 3 * np.max(np.abs(fine.q[:, 7:] - loop))   # growing sawtooth


def test_nonsense_motion_raises_simulation_error():
    model = hanging_loop_model(8)
    coef = model.coef_values()
    eq = static_equilibrium(model, coef, np.zeros(model.n))
    with pytest.raises(vi.SimulationError, match='did not converge'):
        vi.simulate(model, coef, 0.01, eq.q, 1e3 * np.ones(model.n), np.zeros((50, 0)))
