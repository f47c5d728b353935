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


def test_the_pose_is_continuous_and_mirror_symmetric_through_zero_curvature(net):
    """A curvature changing sign at rounding level (an inflection, a straight line) does not move the gripper: the
    odd part (y, rotvec x and z) vanishes at kappa_bar = 0 and is continuous at the blend's edge (without the blend the
    network's y at +-0 differs by up to 0.02 L_gb)."""
    from rod_deploy.planning.neural_controller import ODD_BLEND_KAPPA_BAR
    ls = np.array([1.0, 3.0, 8.0, 20.0])
    ks = np.array([800.0, 2500.0, 800.0, 2500.0])
    p_plus, r_plus = net.predict(ls, ks, 1e-17)
    p_minus, r_minus = net.predict(ls, ks, -1e-17)
    np.testing.assert_allclose(p_plus, p_minus, atol=1e-12)
    np.testing.assert_allclose(r_plus, r_minus, atol=1e-12)
    p0, r0 = net.predict(ls, ks, 0.0)
    np.testing.assert_allclose(p0[:, 1], 0.0, atol=1e-15)
    np.testing.assert_allclose(r0[:, [0, 2]], 0.0, atol=1e-15)
    below, above = ODD_BLEND_KAPPA_BAR * (1 - 1e-9), ODD_BLEND_KAPPA_BAR * (1 + 1e-9)
    for k in (below, -below):
        pb, rb = net.predict(ls, ks, k)
        pa, ra = net.predict(ls, ks, np.copysign(above, k))
        np.testing.assert_allclose(pb, pa, atol=1e-7)
        np.testing.assert_allclose(rb, ra, atol=1e-7)
    # the blend is the network's odd part at the edge scaled linearly, the even part is the network's own
    pm, rm = net.predict(ls, ks, 0.5 * ODD_BLEND_KAPPA_BAR)
    pe, re = net.predict(ls, ks, ODD_BLEND_KAPPA_BAR)
    np.testing.assert_allclose(pm[:, 1], 0.5 * pe[:, 1], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(rm[:, [0, 2]], 0.5 * re[:, [0, 2]], rtol=1e-9, atol=1e-15)
    h = net._forward(np.column_stack([np.log(ls), np.log(ks), np.full(4, 0.5 * ODD_BLEND_KAPPA_BAR)]))
    np.testing.assert_allclose(pm[:, 0], h[:, 0], rtol=1e-12)
    np.testing.assert_allclose(rm[:, 1], h[:, 4], rtol=1e-12)


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
