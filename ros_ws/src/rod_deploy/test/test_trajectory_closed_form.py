"""Alg. 4 planner against closed forms and symmetries: a straight line (the heavy elastica's straight-line limit), a
circle (constant signed curvature, both senses), rigid motions and mirror images of a pattern, the hanging-pose
start of CONTRACTS.md section 4, quaternion continuity and the timing law."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, PlanningError, plan_trajectory, process_pattern

LGB = 0.034
#: the paper's example rod (published planner outputs: h = 2 mm, L_gb = 0.034 m, 0.89 m suspended at the start)
ROD = rod_description_from_dict({'length': 0.89, 'radius': 0.002, 'L_gb': LGB})
#: a thin rod (k_s_bar = 18496) whose stretching under its own weight is small
THIN_ROD = rod_description_from_dict({'length': 0.9, 'radius': 0.0005, 'L_gb': LGB})
#: the inextensible heavy elastica lifted off a rigid floor (independent shooting calculation,
#: ../shared/reference/rod_deployment/README.md): x_bar -> 2.5662, ls_bar - z_bar -> 1.5153 as ls_bar grows
X_BAR_INF, DROP_BAR_INF = 2.5662, 1.5153


def line(origin, heading_rad, length_m, n=61):
    s = np.linspace(0.0, length_m, n)
    return np.column_stack([origin[0] + s * np.cos(heading_rad), origin[1] + s * np.sin(heading_rad)])


def arc(radius_m, turn_rad, ccw=True, n=200):
    """An arc from (0, 0) heading +x, turning left (ccw) or right; its centre is (0, +-radius)."""
    th = np.linspace(0.0, turn_rad, n)
    sgn = 1.0 if ccw else -1.0
    return np.column_stack([radius_m * np.sin(th), sgn * radius_m * (1.0 - np.cos(th))])


def s_curve(n=300):
    """Half a period of a sine on each side: curvature of both signs, 0.3 m long."""
    x = np.linspace(0.0, 0.26, n)
    return np.column_stack([x, 0.03 * np.sin(2 * np.pi * x / 0.26)])


def gripper_axes(plan):
    return Rotation.from_quat(plan.quaternion).as_matrix()


@pytest.mark.parametrize('method, tol_bar', [('numeric', 0.003), ('nn', 0.01)])
def test_straight_line_reaches_the_heavy_elastica_limit(method, tol_bar):
    heading = np.radians(30.0)
    plan = plan_trajectory(line((0.1, -0.2), heading, 0.3), THIN_ROD, PlannerSettings(method=method))
    pat, k = plan.pattern, plan.first_grasp_index
    t = np.array([np.cos(heading), np.sin(heading)])
    # ProcessPattern: nodes on the line, uniform arc length, constant tangent, zero curvature
    np.testing.assert_allclose(pat.tangent, np.tile(t, (len(pat.s), 1)), atol=1e-9)
    np.testing.assert_allclose(pat.xy, np.array([0.1, -0.2]) + pat.s[:, None] * t, atol=1e-9)
    np.testing.assert_allclose(np.diff(pat.s), 0.005)
    np.testing.assert_allclose(pat.kappa, 0.0, atol=1e-6)
    # per-node inputs (Alg. 4): ls_bar = (L - s) / L_gb, k_s_bar = 4 L_gb^2 / h^2, kappa_bar = 0
    ls = (0.9 - pat.s) / LGB
    np.testing.assert_allclose(plan.inputs[:, 0], ls)
    np.testing.assert_allclose(plan.inputs[:, 1], 4 * LGB ** 2 / 0.0005 ** 2)
    np.testing.assert_allclose(plan.inputs[:, 2], 0.0, atol=1e-6)
    # the gripper: ahead of the contact point along the tangent by x_bar L_gb, in the vertical plane of the line,
    # lower than the suspended length by the elastica's drop (plus the stretch under its own weight, ~ls^2/(4 ks))
    rel = plan.position[k:] - np.column_stack([pat.xy, np.full(len(pat.s), THIN_ROD.radius_m)])   # centreline z = h
    along = rel[:, :2] @ t
    across = rel[:, :2] @ np.array([-t[1], t[0]])
    np.testing.assert_allclose(along / LGB, X_BAR_INF, atol=tol_bar)
    np.testing.assert_allclose(across / LGB, 0.0, atol=tol_bar)
    drop = DROP_BAR_INF - ls ** 2 / (4 * THIN_ROD.ks_bar)
    np.testing.assert_allclose(ls - rel[:, 2] / LGB, drop, atol=tol_bar)
    # the rod leaves the gripper straight down (moment-free end)
    z_g = gripper_axes(plan)[k:, :, 2]
    assert np.degrees(np.arccos(np.clip(-z_g[:, 2], -1, 1))).max() < (0.01 if method == 'numeric' else 0.2)


@pytest.mark.parametrize('ccw', [True, False])
def test_circle_constant_signed_curvature_and_gripper_on_the_inside(ccw):
    radius = 0.12
    # Alg. 4 as written: its start, its nodes on the pattern (the closest curve moves them by 20 um on this arc)
    plan = plan_trajectory(arc(radius, 1.2 * np.pi, ccw), ROD,
                           PlannerSettings(method='nn', smoothing_m=0.0, start='tangent', planned_curve='spread'))
    pat, k = plan.pattern, plan.first_grasp_index
    centre = np.array([0.0, radius if ccw else -radius])
    np.testing.assert_allclose(np.linalg.norm(pat.xy - centre, axis=1), radius, atol=1e-5)
    np.testing.assert_allclose(pat.kappa[3:-3], (1 if ccw else -1) / radius, rtol=2e-3)
    # the released sign: a left (counter-clockwise) turn is kappa_bar < 0
    np.testing.assert_allclose(plan.inputs[3:-3, 2], (-1 if ccw else 1) * LGB / radius, rtol=2e-3)
    # constant curvature: the grasp in the local frame depends on ls_bar only, and its lateral offset points to
    # the centre (the suspended rod keeps bending with the pattern)
    left = np.column_stack([-pat.tangent[:, 1], pat.tangent[:, 0]])
    rel = plan.position[k:, :2] - pat.xy
    lateral = np.sum(rel * left, axis=1) * (1 if ccw else -1)             # towards the centre > 0
    assert np.all(lateral[3:-3] > 0.8 * 4 * LGB * LGB / radius)           # about 4 kappa_bar L_gb (paper Fig. 6)
    # the frame mapping q_M = q_C + R_t q_bar L_gb, checked in the centre's polar frame: horizontal distance of the
    # gripper from the centre from the local grasp alone
    qb = plan.grasp_position
    y_in = qb[:, 1] * (1 if ccw else -1)                                   # towards the centre
    expected = np.hypot(radius - y_in * LGB, qb[:, 0] * LGB)
    np.testing.assert_allclose(np.linalg.norm(plan.position[k:, :2] - centre, axis=1), expected, atol=1e-6)
    np.testing.assert_allclose(plan.position[k:, 2], ROD.radius_m + qb[:, 2] * LGB, atol=1e-12)


def test_mirrored_pattern_gives_the_mirrored_trajectory():
    """y -> -y of the pattern (every curvature sign flipped) mirrors positions and gripper frames."""
    pts = s_curve()
    # without the drag compensation: its template (mirrored exactly, test_bend_drag.py) has kappa_bar exactly 0 at
    # the first node of both, where the network's grasp is not its own mirror image (y = -0.013 L_gb at ls_bar 26);
    # so has the looser start's planned curve (share 1.5) here: planned at share 1
    a = plan_trajectory(pts, ROD, PlannerSettings(method='nn', drag_compensation=False, looser_start=False))
    b = plan_trajectory(pts * [1, -1], ROD, PlannerSettings(method='nn', drag_compensation=False, looser_start=False))
    np.testing.assert_allclose(b.inputs[:, 2], -a.inputs[:, 2], atol=1e-9)
    np.testing.assert_allclose(b.position, a.position * [1, -1, 1], atol=1e-9)
    M = np.diag([1.0, -1.0, 1.0])
    Ra, Rb = gripper_axes(a), gripper_axes(b)
    # the rod's exit direction (z_gripper) is a vector: it mirrors; x_gripper (the director d1) mirrors too
    np.testing.assert_allclose(Rb[:, :, 2], Ra[:, :, 2] @ M, atol=1e-9)
    np.testing.assert_allclose(Rb[:, :, 0], Ra[:, :, 0] @ M, atol=1e-9)


def test_rigid_motion_of_the_pattern_moves_the_trajectory_with_it():
    pts = s_curve()
    phi, shift = 2.2, np.array([0.31, -0.07])
    Rz = Rotation.from_euler('z', phi)
    moved = pts @ Rz.as_matrix()[:2, :2].T + shift
    a = plan_trajectory(pts, ROD, PlannerSettings(method='nn'))
    b = plan_trajectory(moved, ROD, PlannerSettings(method='nn'))
    np.testing.assert_allclose(b.inputs, a.inputs, atol=1e-7)
    np.testing.assert_allclose(b.position, Rz.apply(a.position) + np.append(shift, 0.0), atol=1e-8)
    np.testing.assert_allclose(((Rz * a.rotation).inv() * b.rotation).magnitude(), 0.0, atol=1e-7)
    np.testing.assert_allclose(b.t, a.t, atol=1e-6)


@pytest.mark.parametrize('pts', [arc(0.1, 2 * np.pi - 0.3), s_curve()], ids=['full-turn', 's-curve'])
def test_orientation_is_continuous(pts):
    """No quaternion sign flips, and the gripper turns at a finite rate per metre of pattern: halving the node step
    halves every turn between neighbours (a flip or jump would not shrink). A full turn about the vertical passes
    the quaternion through every sign ambiguity; the s-curve twists the gripper about the rod fast where the
    curvature changes sign (the twist-free material frame carried up the suspended rod).
    Alg. 4's tangent start: the friction-limited start (the default) replaces the pattern's start by a curve that
    depends on the node step, so the two steps would not plan the same curve; without the drag compensation for the
    same reason (its template depends on the node step: on this s-curve at most 0.6 mm off the pattern at 5 mm
    steps, 1.4 mm at 2.5 mm, which turns the gripper by up to 1.1 degrees more over a 5 mm step)."""
    turns = []
    step_m = 0.005
    for _ in range(2):
        plan = plan_trajectory(pts, ROD, PlannerSettings(method='nn', step_m=step_m, start='tangent',
                                                         drag_compensation=False))
        step_m = 0.5 * plan.pattern.s[1]          # the nodes at most step_m apart: halve the spacing actually used
        q = plan.quaternion
        np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
        assert np.all(np.sum(q[1:] * q[:-1], axis=1) > 0)
        k = plan.first_grasp_index
        turn = (plan.rotation[k:-1].inv() * plan.rotation[k + 1:]).magnitude()
        assert np.degrees(turn).max() < 10.0
        turns.append(turn)
        # over the lead-in, the slerp turns by equal steps
        lead = (plan.rotation[:k].inv() * plan.rotation[1:k + 1]).magnitude()
        np.testing.assert_allclose(lead, lead.mean(), atol=1e-9)
    # between common nodes (about every 5 mm) the two half steps add up to the whole step: no jump hides in between
    # (to 1 degree: where the curvature changes sign the twist rate varies within a step, and where the smoothing
    # spline's curvature has a kink, at a knot, the gripper's turn changes direction within a step: 0.75 degrees in
    # two half steps against 0.15 in the whole step on this s-curve once the nodes no longer fall on the knot)
    coarse, fine = turns
    n = min(len(coarse), len(fine) // 2)
    np.testing.assert_allclose(fine[0:2 * n:2] + fine[1:2 * n:2], coarse[:n], rtol=0.02, atol=np.radians(1.0))


def test_hanging_pose_start_and_straight_lead_in():
    """CONTRACTS.md section 4: the trajectory starts with the rod hanging straight, free end on the table at the
    pattern's first point, gripper above it; a straight lead-in to the first grasp."""
    plan = plan_trajectory(arc(0.15, 1.5), ROD, PlannerSettings(method='nn', lead_in_poses=10))
    k = plan.first_grasp_index
    assert k == 10
    # at rest with the free end just touching the table: L + h + the stretch under its own weight, L^2 / (4 L_gb ks_bar)
    stretch = 0.89 ** 2 / (4 * LGB * 4 * LGB ** 2 / 0.002 ** 2)
    assert 0.0049 < stretch < 0.0051                                      # rho g L^2 / (2 E) for rod #3: 5.0 mm
    np.testing.assert_allclose(plan.position[0], [*plan.pattern.xy[0], 0.89 + 0.002 + stretch], atol=1e-12)
    R = gripper_axes(plan)
    np.testing.assert_allclose(R[0][:, 2], [0, 0, -1], atol=1e-12)
    # the hanging gripper is turned like the first grasp about the vertical (no twist jump in the lead-in)
    x_first = R[k][:, 0] - R[k][2, 0] * np.array([0, 0, 1])
    np.testing.assert_allclose(R[0][:, 0], x_first / np.linalg.norm(x_first), atol=1e-12)
    # positions of the lead-in on the segment from the hanging pose to the first grasp, equally spaced
    d = plan.position[1:k + 1] - plan.position[:k]
    np.testing.assert_allclose(d, np.tile(d[0], (k, 1)), atol=1e-12)
    # the exact contract example: a straight pattern along -x with the numeric grasps hangs with (1, 0, 0, 0)
    numeric = plan_trajectory(line((0.0, 0.0), np.pi, 0.05, 11), ROD, PlannerSettings(method='numeric'))
    np.testing.assert_allclose(numeric.quaternion[0], [1, 0, 0, 0], atol=1e-9)


def test_timing_law():
    """Each segment at the gripper speed unless the turning-rate cap is slower; t strictly increasing from 0."""
    settings = PlannerSettings(method='nn', speed_m_s=0.02, max_angular_rate_rad_s=0.05)
    plan = plan_trajectory(arc(0.08, 4.0), ROD, settings)
    t, p = plan.t, plan.position
    assert t[0] == 0.0 and np.all(np.diff(t) > 0)
    dt = np.diff(t)
    v = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
    w = (plan.rotation[:-1].inv() * plan.rotation[1:]).magnitude() / dt
    assert v.max() <= 0.02 * (1 + 1e-9) and w.max() <= 0.05 * (1 + 1e-6)
    # every segment is at one of its two limits
    at_limit = np.isclose(v, 0.02, rtol=1e-6) | np.isclose(w, 0.05, rtol=1e-4)
    assert at_limit.all()
    assert np.isclose(w, 0.05, rtol=1e-4).any() and np.isclose(v, 0.02, rtol=1e-6).any()
    # a straight pattern: no turning, so the duration is the gripper path length over the speed
    straight = plan_trajectory(line((0, 0), 0.0, 0.2), ROD, PlannerSettings(method='nn', speed_m_s=0.01))
    path = np.linalg.norm(np.diff(straight.position, axis=0), axis=1).sum()
    assert straight.t[-1] == pytest.approx(path / 0.01, rel=1e-3)


def test_network_and_numeric_planners_agree_on_an_s_curve():
    """Both signs of curvature, ls_bar 26 -> 18: the network against the continuation it was trained to replace."""
    pts = s_curve()
    a = plan_trajectory(pts, ROD, PlannerSettings(method='nn', step_m=0.01))
    b = plan_trajectory(pts, ROD, PlannerSettings(method='numeric', step_m=0.01))
    np.testing.assert_allclose(a.inputs, b.inputs)
    k = a.first_grasp_index
    gap_mm = np.linalg.norm(a.position[k:] - b.position[k:], axis=1) * 1e3
    assert gap_mm.mean() < 0.5 and gap_mm.max() < 1.0
    ang = np.degrees((a.rotation[k:].inv() * b.rotation[k:]).magnitude())
    assert ang.max() < 0.3


def test_errors_name_the_offending_point():
    # a straight pattern with one tight bend (radius 5 mm) around (0.1, 0.005)
    th = np.linspace(-np.pi / 2, np.pi / 2, 40)[1:-1]
    bend = np.column_stack([0.1 + 0.005 * np.cos(th), 0.005 + 0.005 * np.sin(th)])
    pts = np.vstack([line((0, 0), 0.0, 0.1, 21), bend, line((0.1, 0.01), np.pi, 0.1, 21)])
    with pytest.raises(PlanningError, match='bends too sharply') as e:
        plan_trajectory(pts, ROD, PlannerSettings(method='nn', smoothing_m=0.0))
    x, y = (float(v) for v in str(e.value).split(') m')[0].split('(')[-1].split(','))
    assert np.hypot(x - 0.1, y - 0.005) < 0.006                  # a point of the bend, not of the straight parts
    # too long: the node where less than 0.5 L_gb would remain suspended, and the longest pattern that fits
    with pytest.raises(PlanningError, match=r'patterns up to 0\.873 m fit this rod') as e:
        plan_trajectory(line((0, 0), 0.0, 0.95, 191), ROD, PlannerSettings(method='nn'))
    x = float(str(e.value).split('node ')[1].split('(')[1].split(',')[0])
    assert x == pytest.approx(0.89 - 0.5 * LGB, abs=0.005)


def test_spline_keeps_the_first_point_and_the_start_direction():
    """A straight start (5 mm points, as the published circle's) then an arc of radius 0.1 m: the smoothing spline
    stays on the first point and closer to the start's direction and zero curvature than with equal weights (0.62
    mm, 2.8 degrees, kappa_bar -0.20 there; now 0.02 mm, 0.9 degrees, -0.10: the curvature jump at the arc is
    smeared over a few centimetres either way)."""
    straight = np.column_stack([np.zeros(17), -0.005 * np.arange(17)])
    bend = arc(0.1, 1.5 * np.pi, n=95)[1:] @ np.array([[0.0, -1.0], [1.0, 0.0]]) + straight[-1]
    pts = np.vstack([straight, bend])
    p = process_pattern(pts)
    assert np.linalg.norm(p.xy[0] - pts[0]) < 1e-4
    assert abs(np.degrees(np.arctan2(p.tangent[0, 0], -p.tangent[0, 1]))) < 1.5
    assert abs(p.kappa[0]) * LGB < 0.15
    np.testing.assert_allclose(np.median(p.kappa[40:-5]) * 0.1, 1.0, atol=0.05)


@pytest.mark.parametrize('length', [0.1975, 0.2, 0.2049])
def test_the_nodes_run_to_the_end_of_the_pattern(length):
    """Alg. 4 lays the whole pattern: its last node is the pattern's end, the nodes uniformly at most step_m apart
    (with exactly step_m the last up to one step was never planned: 4.9 mm of the paper's circle)."""
    pts = np.column_stack([np.linspace(0.0, length, 80), np.zeros(80)])
    pat = process_pattern(pts, step_m=0.005, smoothing_m=0.0)
    assert pat.s[-1] == pytest.approx(length, abs=1e-6)
    np.testing.assert_allclose(pat.xy[-1], [length, 0.0], atol=1e-6)
    gaps = np.diff(pat.s)
    assert np.all(gaps <= 0.005 + 1e-12) and np.ptp(gaps) < 1e-12
    plan = plan_trajectory(pts, ROD, PlannerSettings(method='nn'))
    np.testing.assert_allclose(plan.pattern.xy[-1], [length, 0.0], atol=1e-6)


def test_process_pattern_resamples_uniformly_by_arc_length():
    """Unevenly spaced points on a circle: nodes uniformly by arc length, at most step_m (4 mm) apart, on the
    circle from its first point to its last."""
    rng = np.random.default_rng(3)
    th = np.sort(rng.uniform(0, 3.0, 80))
    th[0] = 0.0
    pts = 0.2 * np.column_stack([np.sin(th), 1 - np.cos(th)])
    pat = process_pattern(pts, step_m=0.004, smoothing_m=0.0)
    arc = 0.2 * th[-1]
    ds = arc / np.ceil(arc / 0.004)                                 # the largest spacing <= 4 mm that divides it
    assert pat.s[-1] == pytest.approx(arc, rel=1e-4)
    chord = np.linalg.norm(np.diff(pat.xy, axis=0), axis=1)
    np.testing.assert_allclose(chord, 2 * 0.2 * np.sin(ds / 0.4), rtol=1e-3)      # the chord of ds of arc
    np.testing.assert_allclose(np.linalg.norm(pat.xy - [0, 0.2], axis=1), 0.2, atol=2e-5)
