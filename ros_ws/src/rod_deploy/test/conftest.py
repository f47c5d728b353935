"""Fixtures shared by the rod_deploy tests."""
import numpy as np
import pytest

from rod_deploy.physics.der_simulator import DiscreteElasticRod, RodParameters


@pytest.fixture
def clamped_cantilever():
    """Factory of the swinging cantilever: a 1 m rod of N edges along x (EI 0.05, EA 500, GJ 0.03, rho A 1, radius
    1 cm, gravity -z), its first edge clamped (nodes 0 and 1 and the first twist), released from straight."""
    def make(N=12):
        x = np.c_[np.linspace(0, 1, N + 1), np.zeros(N + 1), np.zeros(N + 1)]
        rod = DiscreteElasticRod(x, RodParameters(EI=0.05, EA=500.0, GJ=0.03, rho_A=1.0, radius=0.01,
                                                  gravity=(0, 0, -1)))
        rod.clamp_node(0)
        rod.clamp_node(1)
        rod.clamp_theta(0)
        return rod
    return make
