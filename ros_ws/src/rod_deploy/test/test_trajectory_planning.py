"""Alg. 4 planner: pattern processing, per-node inputs, the contract's gripper frame, timing, errors."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rod_deploy.planning.pattern_input import PatternError, check_pattern
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, PlanningError, plan_trajectory, process_pattern

ROD = rod_description_from_dict({'length': 0.89, 'radius': 0.002, 'L_gb': 0.034})


def circle(radius, turn, ccw=True, n=200):
    th = np.linspace(0, turn, n)
    sgn = 1 if ccw else -1
    return np.column_stack([radius * np.sin(th), sgn * radius * (1 - np.cos(th))])   # starts at 0 heading +x


@pytest.mark.parametrize('ccw', [True, False])
def test_circle_curvature_sign_and_value(ccw):
    pat = process_pattern(circle(0.12, np.pi, ccw), step_m=0.005, smoothing_m=0.0)
    inner = pat.kappa[5:-5]
    np.testing.assert_allclose(inner, (1 if ccw else -1) / 0.12, rtol=0.01)
    np.testing.assert_allclose(np.diff(pat.s), 0.005, atol=1e-4)
    np.testing.assert_allclose(np.linalg.norm(pat.tangent, axis=1), 1.0)
    assert pat.length == pytest.approx(0.12 * np.pi, abs=0.006)


def test_node_inputs_follow_alg4():
    plan = plan_trajectory(circle(0.12, np.pi), ROD, PlannerSettings(method='nn', smoothing_m=0.0, start='tangent'))
    s = plan.pattern.s
    np.testing.assert_allclose(plan.inputs[:, 0], (0.89 - s) / 0.034)                  # ls_bar = (L - s) / L_gb
    np.testing.assert_allclose(plan.inputs[:, 1], 4 * 0.034 ** 2 / 0.002 ** 2)          # ks_bar
    # a counter-clockwise (left) turn is a negative kappa_bar in the released sign, and puts the gripper on the left
    np.testing.assert_allclose(plan.inputs[5:-5, 2], -0.034 / 0.12, rtol=0.01)
    k = plan.first_grasp_index
    left = np.column_stack([-plan.pattern.tangent[:, 1], plan.pattern.tangent[:, 0]])
    offset = plan.position[k + 20, :2] - plan.pattern.xy[20]
    assert np.dot(offset, left[20]) > 0.03                                              # about 4 L_gb kappa_bar


def test_hanging_start_gripper_frame_and_continuity():
    plan = plan_trajectory(circle(0.15, 1.5), ROD, PlannerSettings(method='nn'))
    R = Rotation.from_quat(plan.quaternion).as_matrix()
    assert plan.position[0, 2] == pytest.approx(ROD.hanging_height_m)            # hanging: L + radius + stretch
    np.testing.assert_allclose(plan.position[0, :2], plan.pattern.xy[0], atol=1e-9)
    np.testing.assert_allclose(R[0][:, 2], [0, 0, -1], atol=1e-9)                      # +z_gripper down
    # the rod leaves the gripper downwards and slightly backwards along the pattern at every grasp
    z_g = R[plan.first_grasp_index:, :, 2]
    assert np.all(z_g[:, 2] < -0.9)
    assert np.all(np.sum(plan.quaternion[1:] * plan.quaternion[:-1], axis=1) > 0.99)  # no flips between poses
    assert np.all(np.diff(plan.t) > 0)
    speed = np.linalg.norm(np.diff(plan.position, axis=0), axis=1) / np.diff(plan.t)
    assert speed.max() <= 0.01 + 1e-9
    # a pattern starting along -x hangs with the quaternion (1, 0, 0, 0) (CONTRACTS.md section 4)
    line = np.column_stack([-np.linspace(0, 0.3, 61), np.zeros(61)])
    q0 = plan_trajectory(line, ROD, PlannerSettings(method='nn')).quaternion[0]
    np.testing.assert_allclose(np.abs(q0), [1, 0, 0, 0], atol=2e-3)              # the network: 0.1 deg


def test_intuitive_baseline_is_straight_above_the_contact_point():
    plan = plan_trajectory(circle(0.15, 1.5), ROD, PlannerSettings(method='intuitive'))
    k = plan.first_grasp_index
    np.testing.assert_allclose(plan.position[k:, :2], plan.pattern.xy, atol=1e-12)
    np.testing.assert_allclose(plan.position[k:, 2], 0.002 + 0.89 - plan.pattern.s)   # centreline at z = h
    # it descends by the length laid: a 45-degree path
    d = np.diff(plan.position[k:], axis=0)
    np.testing.assert_allclose(-d[:, 2], np.linalg.norm(d[:, :2], axis=1), rtol=0.02)


def test_network_and_numeric_planners_agree_on_a_short_pattern():
    pts = circle(0.2, 0.8)
    a = plan_trajectory(pts, ROD, PlannerSettings(method='nn'))
    b = plan_trajectory(pts, ROD, PlannerSettings(method='numeric'))
    k = a.first_grasp_index
    gap = np.linalg.norm(a.position[k:] - b.position[k:], axis=1)
    assert gap.max() < 0.002                                                            # 2 mm
    ang = (a.rotation[k:].inv() * b.rotation[k:]).magnitude()
    assert np.degrees(ang).max() < 0.5


@pytest.mark.parametrize('points, words', [
    (np.column_stack([np.linspace(0, 0.95, 100), np.zeros(100)]), 'longer than the rod allows'),
    (circle(0.006, 3.0), 'bends too sharply'),
    (np.array([[0, 0], [0.1, 0]]), 'at least 3 points'),
    (np.array([[0, 0], [0.1, 0], [np.nan, 0.1], [0.2, 0]]), 'not finite'),
    (np.array([[0, 0], [0.1, 0], [0.1, 0], [0.2, 0]]), 'repeats point'),
])
def test_bad_patterns_are_refused_with_the_point(points, words):
    with pytest.raises((PlanningError, PatternError), match=words):
        plan_trajectory(points, ROD, PlannerSettings(method='nn'))


def test_check_pattern_names_the_point():
    with pytest.raises(PatternError, match=r'point 2 \(0.1, 0\) repeats point 1'):
        check_pattern(np.array([[0, 0], [0.1, 0], [0.1, 0], [0.3, 0]]))
