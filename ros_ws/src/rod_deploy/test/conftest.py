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


@pytest.fixture
def rounded_zigzag():
    """The acceptance rehearsal's zig-zag: legs at +-45 degrees, 90-degree corners rounded to ``radius_m``
    (|kappa_bar| 1.4 for rod #3), 5 corners, legs 9.9 cm between the corner points (0.07 m apart in x)."""
    radius_m, corners, leg_m = 0.025, 5, 0.07 * np.sqrt(2)
    pts, heading, p = [np.zeros(2)], np.pi / 4, np.zeros(2)
    for k in range(corners + 1):
        straight = leg_m - 2 * radius_m * np.tan(np.pi / 4) if 0 < k < corners else leg_m - radius_m
        for u in np.linspace(0, straight, 40)[1:]:
            pts.append(p + u * np.array([np.cos(heading), np.sin(heading)]))
        p = pts[-1]
        if k == corners:
            break
        turn = -np.pi / 2 if k % 2 == 0 else np.pi / 2
        centre = p + radius_m * np.sign(turn) * np.array([-np.sin(heading), np.cos(heading)])
        a0 = np.arctan2(*(p - centre)[::-1])
        for a in np.linspace(a0, a0 + turn, 30)[1:]:
            pts.append(centre + radius_m * np.array([np.cos(a), np.sin(a)]))
        p, heading = pts[-1], heading + turn
    return np.array(pts)
