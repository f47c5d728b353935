"""A time step whose Newton iteration does not converge is never accepted: the DER step refuses it (state kept),
and the deployment simulation retries it as half steps, or fails with a clear error."""
import numpy as np
import pytest

from rod_deploy.deployment.simulate import DeploymentError, SimulationSettings, simulate_deployment
from rod_deploy.physics.der_simulator import DiscreteElasticRod, NewtonNotConverged
from rod_deploy.planning.rod_description import rod_description_from_dict


def test_a_step_that_does_not_converge_is_refused_and_the_state_kept(clamped_cantilever):
    rod = clamped_cantilever()
    q, u, t = rod.state.q.copy(), rod.state.u.copy(), rod.state.time
    with pytest.raises(NewtonNotConverged, match='did not converge') as err:
        rod.step(0.2, max_iter=1)                # a large, nonlinear step: one Newton iteration is not enough
    assert err.value.iterations == 1 and err.value.residual > err.value.tolerance
    np.testing.assert_array_equal(rod.state.q, q)
    np.testing.assert_array_equal(rod.state.u, u)
    assert rod.state.time == t
    assert rod.step(0.2) < 40                     # with the default iterations it converges
    assert rod.state.time == pytest.approx(t + 0.2)


ROD = rod_description_from_dict({'length': 0.2, 'radius': 0.002, 'L_gb': 0.034, 'friction': 0.5})


def _hang(settings):
    p = np.array([0.0, 0.0, ROD.hanging_height_m])
    q = np.array([1.0, 0.0, 0.0, 0.0])
    return simulate_deployment([0.0, 0.1], [p, p], [q, q], ROD, settings)


def test_the_deployment_retries_a_failed_step_as_half_steps(monkeypatch):
    settings = SimulationSettings(edge_length_m=0.01, settle_s=0.1, dt_s=0.02)
    reference = _hang(settings)
    assert reference.halved_steps == 0 and reference.smallest_step_s == 0.02
    assert 1 <= reference.max_newton_iterations < 40
    step = DiscreteElasticRod.step
    failed = []

    def flaky(self, dt, **kw):                  # the third full step fails once, as a non-converged Newton would
        if dt == settings.dt_s and self.state.time > 0.03 and not failed:
            failed.append(self.state.time)
            raise NewtonNotConverged(self.state.time + dt, dt, 40, 1.0, 1e-9)
        return step(self, dt, **kw)

    monkeypatch.setattr(DiscreteElasticRod, 'step', flaky)
    res = _hang(settings)
    assert failed and res.halved_steps == 1 and res.smallest_step_s == 0.01
    assert res.steps == reference.steps
    np.testing.assert_allclose(res.nodes, reference.nodes, atol=1e-6)     # the same hanging rod


def test_a_step_that_never_converges_fails_the_deployment(monkeypatch):
    def never(self, dt, **kw):
        raise NewtonNotConverged(self.state.time + dt, dt, 40, 1.0, 1e-9)

    monkeypatch.setattr(DiscreteElasticRod, 'step', never)
    with pytest.raises(DeploymentError, match=r'did not converge at t = 0\.0003 s, even with steps of 0\.0003'):
        _hang(SimulationSettings(edge_length_m=0.01, settle_s=0.1, dt_s=0.02))
