"""The shipped grasp network against fresh numeric solves it was never trained on (off the dataset's grid)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rod_deploy.planning.neural_controller import OutOfTrainedRange, load_grasp_network, mirror
from rod_deploy.planning.optimal_grasp import optimal_grasp

# off-grid inputs in the planner's region (ls_bar, ks_bar, kappa_bar released sign)
POINTS = [(13.0, 1156.0, 0.3), (21.7, 1600.0, 0.05), (5.3, 900.0, 0.8), (2.2, 2500.0, 0.15), (26.0, 1156.0, 0.0)]


@pytest.fixture(scope='module')
def net():
    return load_grasp_network()


def test_matches_fresh_numeric_solves(net):
    x = np.array(POINTS)
    p, r = net.predict(x[:, 0], x[:, 1], x[:, 2])
    for (ls, ks, kap), pi, ri in zip(POINTS, p, r):
        g = optimal_grasp(ls, kap, ks, check_stability=False)
        # benchmark: 0.39 mm mean, 1.3 mm max for L_gb = 3.3 cm in this region -> 0.06 L_gb is a wide margin
        assert np.linalg.norm(pi - g.position) < 0.06, (ls, ks, kap, pi, g.position)
        angle = (Rotation.from_rotvec(ri).inv() * Rotation.from_rotvec(g.rotvec)).magnitude()
        assert np.degrees(angle) < 0.5, (ls, ks, kap)


def test_negative_curvature_is_the_mirror_image(net):
    p_pos, r_pos = net.predict(13.0, 1156.0, 0.4)
    p_neg, r_neg = net.predict(13.0, 1156.0, -0.4)
    mp, mr = mirror(p_pos, r_pos)
    np.testing.assert_allclose(p_neg, mp)
    np.testing.assert_allclose(r_neg, mr)
    g = optimal_grasp(13.0, -0.4, 1156.0, check_stability=False)       # and the solver agrees
    assert np.linalg.norm(p_neg[0] - g.position) < 0.06
    assert g.position[1] > 0 > p_pos[0, 1]                              # released sign: kappa > 0 puts y < 0


def test_outside_the_trained_range_is_refused(net):
    lo, hi = net.trained_range['ls_bar']
    with pytest.raises(OutOfTrainedRange, match='ls_bar'):
        net.predict([10.0, hi * 1.5], 1156.0, 0.1)
    with pytest.raises(OutOfTrainedRange, match='kappa'):
        net.predict(10.0, 1156.0, net.trained_range['abs_kappa_bar'][1] + 0.5)
    with pytest.raises(OutOfTrainedRange, match='ks_bar'):
        net.predict(10.0, 10.0, 0.1)
    with pytest.raises(OutOfTrainedRange):
        net.predict(np.nan, 1156.0, 0.1)


def test_broadcasting_and_shapes(net):
    p, r = net.predict(np.linspace(5, 20, 7), 1156.0, 0.2)
    assert p.shape == (7, 3) and r.shape == (7, 3)
    p1, _ = net.predict(12.0, 1156.0, 0.2)
    assert p1.shape == (1, 3)
    assert net.record['held_out'] > 0 and net.record['width'] > 0          # the record of its training ships too
