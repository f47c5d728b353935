"""The curvature rate limit of the planner (curvature_rate.py) and what it and the friction check do to a plan: a
sudden change of curvature is spread over a ramp (the turning kept), the gripper no longer jumps by a large part of
the suspended length per node, and a bend friction cannot hold is refused with the point named."""
import numpy as np
import pytest

from rod_deploy.planning.curvature_rate import default_max_rate, levenberg_marquardt, limit_curvature_rate
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, PlanningError, plan_trajectory

LGB, STEP = 0.034, 0.005
ROD = rod_description_from_dict({'length': 0.89, 'radius': 0.002, 'L_gb': LGB, 'friction': 0.5})


def lead_then_curl(lead_m, radius_m, turn_rad=np.pi):
    """A straight lead along +y, then a turn to the left of ``radius_m``: a jump of the curvature."""
    line = np.column_stack([np.zeros(200), np.linspace(0.0, lead_m, 200)])
    th = np.linspace(0.0, turn_rad, 100)[1:]
    return np.vstack([line, np.column_stack([-radius_m + radius_m * np.cos(th), lead_m + radius_m * np.sin(th)])])


def test_a_step_becomes_a_ramp_at_the_rate_with_the_turning_kept():
    k = np.r_[np.zeros(60), np.full(60, 2.0)]
    h = STEP / LGB
    out = limit_curvature_rate(k, h, 0.5)
    assert np.abs(np.diff(out)).max() <= 0.5 * h * 1.011                   # the limit (1 % tolerance of the solver)
    assert out.sum() == pytest.approx(k.sum(), rel=1e-12)                   # the pattern's turning is kept
    assert np.all(np.diff(out) >= -1e-12)                                   # monotone: no overshoot
    ramp = np.flatnonzero((out > 0.01) & (out < 1.99))
    assert len(ramp) * h == pytest.approx(2.0 / 0.5, rel=0.1)               # 4 L_gb long, centred on the step
    assert ramp.mean() == pytest.approx(59.5, abs=1.0)
    np.testing.assert_array_equal(out[:30], 0.0)                            # untouched away from the step
    np.testing.assert_array_equal(out[-30:], 2.0)


def test_a_curvature_within_the_rate_is_unchanged():
    s_bar = np.arange(200) * STEP / LGB
    k = 0.8 * np.sin(s_bar / 4.0)                                           # rate at most 0.2 per L_gb
    np.testing.assert_array_equal(limit_curvature_rate(k, STEP / LGB, 0.25), k)
    np.testing.assert_array_equal(limit_curvature_rate(k, STEP / LGB, np.inf), k)
    with pytest.raises(ValueError):
        limit_curvature_rate(k, STEP / LGB, 0.0)
    with pytest.raises(PlanningError, match='max_kappa_bar_rate'):
        plan_trajectory(lead_then_curl(0.3, 0.05), ROD, PlannerSettings(max_kappa_bar_rate=-1.0))


def test_no_gripper_jump_where_the_curvature_jumps():
    # a 30 cm lead, then a curl of radius 1.7 cm (kappa_bar 2): the pattern's curvature jumps by 2 within a node,
    # and with it the optimal grasp, by about 20 cm at ls_bar 17 (28 cm per 5 mm node before the rate limit)
    pts = lead_then_curl(0.3, 0.017)
    plan = plan_trajectory(pts, ROD, PlannerSettings(planned_curve='spread', drag_compensation=False))
    # Alg. 4: the pattern's own (no drag compensation, whose template rounds the curl: the jump itself is tested)
    raw = plan_trajectory(pts, ROD, PlannerSettings(max_kappa_bar_rate=np.inf, drag_compensation=False))
    # the grasp in the pattern's local frame: at most rate x node spacing x |dq/dkappa_bar| (6 L_gb) per node
    local = np.linalg.norm(np.diff(plan.grasp_position, axis=0), axis=1) * LGB
    assert local.max() < 0.015
    assert np.linalg.norm(np.diff(raw.grasp_position, axis=0), axis=1).max() * LGB > 0.10
    # in the table frame the gripper also orbits the contact point with the tangent (20 cm out, 17 degrees per
    # node on the curl): a smooth motion, no longer a jump
    k = plan.first_grasp_index
    assert np.linalg.norm(np.diff(plan.position[k:], axis=0), axis=1).max() < 0.08
    assert np.linalg.norm(np.diff(raw.position[k:], axis=0), axis=1).max() > 0.14
    # spread: the contact points and tangents are the pattern's, only the curvature asked of the grasp solver changes
    np.testing.assert_allclose(plan.pattern.xy, raw.pattern.xy)
    assert np.sum(plan.inputs[:, 2]) == pytest.approx(np.sum(raw.inputs[:, 2]), rel=1e-9)
    # closest (the default): the nodes on one curve with the limited curvature; the gripper does not jump either
    closest = plan_trajectory(pts, ROD, PlannerSettings())
    assert np.linalg.norm(np.diff(closest.grasp_position, axis=0), axis=1).max() * LGB < 0.015
    assert np.linalg.norm(np.diff(closest.position[k:], axis=0), axis=1).max() < 0.08


def test_a_bend_friction_cannot_hold_is_refused_with_the_point():
    # the acceptance rehearsal's hook: a 5 cm stem and a half turn of radius 1.6 cm at its end; the laid 5-10 cm
    # cannot hold the curl's moment at friction 0.5 (simulated: the whole hook turned, e_mean 9 cm)
    hook = lead_then_curl(0.05, 0.016)
    with pytest.raises(PlanningError, match=r'cannot hold the pattern\'s bend at node \d+ \(-?0\.\d{4}, 0\.\d{4}\) m, '
                                            r'0\.\d{3} m from the free end: \|kappa_bar\| = 2\.\d\d '
                                            r'\(radius 0\.01\d m\)') as e:
        plan_trajectory(hook, ROD, PlannerSettings())
    assert 'friction 0.5' in str(e.value) and 'm of rod on the table before it' in str(e.value)
    # on a table with ten times the friction the same hook is planned (simulated: e_mean 0.37 cm)
    plan_trajectory(hook, ROD, PlannerSettings(friction=5.0))
    # the intuitive baseline lays no bend moment, and the experiment switch plans it anyway
    plan_trajectory(hook, ROD, PlannerSettings(method='intuitive'))
    plan_trajectory(hook, ROD, PlannerSettings(check_friction=False))


def test_the_default_rate_scales_with_the_square_root_of_friction():
    # a change d kappa_bar needs a ramp of about L_gb sqrt(8 d kappa_bar / mu): its slope scales with sqrt(mu)
    assert default_max_rate(0.5) == pytest.approx(0.35)
    assert default_max_rate(2.0) == pytest.approx(0.70)
    # a 20 cm lead into an arc of radius 6 cm (kappa_bar 0.57 at once): spread at friction 0.5, less at 2 (the
    # closest curve need not use all of the rate it may: at 2 it lies within 0.4 mm of the pattern at 0.37 per L_gb)
    pts = lead_then_curl(0.2, 0.06, turn_rad=2.0)
    h = STEP / LGB
    rates = {}
    for mu in (0.5, 2.0):
        for planned_curve in ('spread', 'closest'):
            plan = plan_trajectory(pts, ROD, PlannerSettings(friction=mu, planned_curve=planned_curve))
            rates[mu, planned_curve] = np.abs(np.diff(plan.inputs[:, 2])).max() / h
            assert rates[mu, planned_curve] <= default_max_rate(mu) * 1.011
    assert rates[2.0, 'spread'] > 1.5 * rates[0.5, 'spread']


def test_the_closest_curve_keeps_the_limits_and_stays_nearer_the_pattern_than_the_spread_bends(rounded_zigzag):
    """A rounded zig-zag asks |kappa_bar| 1.4 at its corners, 4 times more than the rate 0.35 per L_gb reaches in a
    corner: spread symmetrically, each widened corner shortens the curve and the later nodes lag along the pattern
    (4.3 cm e_mean simulated on the rehearsal's zig-zag). The closest curve respects the same limits, is one curve
    (points, tangents and curvature agree) and lies nearer the pattern at equal arc length."""
    from rod_deploy.planning.achievable_start import friction_curvature_limit, integrate_curvature
    from rod_deploy.deployment.metrics import eq17_error
    pts = rounded_zigzag
    # the planned curves for the pattern itself (no drag compensation: bend_drag.py's template is tested there)
    spread = plan_trajectory(pts, ROD, PlannerSettings(planned_curve='spread', drag_compensation=False))
    closest = plan_trajectory(pts, ROD, PlannerSettings(drag_compensation=False))
    given, h = closest.drawn_pattern, STEP / LGB
    assert abs(given.kappa).max() * LGB > 1.3
    kb = closest.inputs[:, 2]
    # (1 % the tolerance of limit_curvature_rate, 2 % the clip to the start's friction cap after it)
    assert np.abs(np.diff(kb)).max() <= default_max_rate(0.5) * h * 1.03
    assert np.all(np.abs(kb) <= friction_curvature_limit(given.s, LGB, 0.5) * LGB + 1e-9)
    # one curve: its curvature integrated from its first point and tangent gives its points and tangents
    c = closest.pattern
    xy, theta = integrate_curvature(c.s, np.arctan2(c.tangent[0, 1], c.tangent[0, 0]), c.kappa, c.xy[0])
    np.testing.assert_allclose(xy, c.xy, atol=1e-9)
    np.testing.assert_allclose(-c.kappa * LGB, kb, atol=1e-9)
    np.testing.assert_allclose(closest.asked_xy, c.xy, atol=1e-6)
    np.testing.assert_allclose(c.xy[0], given.xy[0], atol=1e-9)                 # the free end on the pattern
    # nearer the pattern than the spread curvature's curve, by a wide margin
    e_spread = eq17_error(given.xy, spread.asked_xy)['e_mean_cm']
    e_closest = eq17_error(given.xy, closest.asked_xy)['e_mean_cm']
    assert e_closest < 0.7 * e_spread
    assert closest.asked_deviation()[0] < spread.asked_deviation()[0]


def test_a_pattern_within_the_limits_is_planned_on_itself():
    # a circle arc of radius 2 L_gb (kappa_bar 0.5) after a 25 cm lead ramped in within the rate: nothing to change
    s = np.linspace(0, 0.55, 400)
    sb = s / LGB
    ramp_start, ramp_len = 0.25 / LGB, 0.5 / 0.3
    kb = 0.5 * np.clip((sb - ramp_start) / ramp_len, 0, 1)
    from rod_deploy.planning.achievable_start import integrate_curvature
    pts, _ = integrate_curvature(s, 0.3, kb / LGB, np.zeros(2))
    # (the drag compensation, bend_drag.py, would move the bend: at friction 0.5 the touch-down point cannot hold
    # kappa_bar 0.5 with its ramp; the curve planned for the pattern itself is tested here)
    plan = plan_trajectory(pts, ROD, PlannerSettings(drag_compensation=False))
    assert plan.asked_deviation()[0] < 5e-4
    assert np.linalg.norm(plan.pattern.xy - plan.drawn_pattern.xy, axis=1).max() < 5e-4
    # whichever curve is planned on, it is the nearer of the two to the pattern (mean distance over the nodes)
    spread = plan_trajectory(pts, ROD, PlannerSettings(planned_curve='spread', drag_compensation=False))
    near = [np.mean(np.linalg.norm(p.asked_xy - p.drawn_pattern.xy, axis=1)) for p in (plan, spread)]
    assert near[0] <= near[1]
    with pytest.raises(PlanningError, match='planned_curve'):
        plan_trajectory(pts, ROD, PlannerSettings(planned_curve='nearest'))


def test_levenberg_marquardt_reaches_the_minimum_scipy_reaches():
    """The closest curve's solver: on Rosenbrock's valley (residuals 10 (y - x^2), 1 - x; minimum at (1, 1)) from
    the textbook start, and on a nonlinear fit with noise (a damped oscillation), it ends where scipy's
    least_squares run to tight tolerances ends."""
    from scipy.optimize import least_squares

    def rosen(x):
        return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])

    def rosen_jac(x):
        return np.array([[-20.0 * x[0], 10.0], [-1.0, 0.0]])

    def normal(jac):
        return lambda x, r: (jac(x).T @ jac(x), jac(x).T @ r)

    np.testing.assert_allclose(levenberg_marquardt(rosen, normal(rosen_jac), np.array([-1.2, 1.0])), [1.0, 1.0],
                               atol=1e-8)

    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 4.0, 80)
    y = 2.0 * np.exp(-0.7 * t) * np.cos(3.0 * t + 0.4) + 0.02 * rng.standard_normal(t.size)

    def fit(p):
        return p[0] * np.exp(-p[1] * t) * np.cos(p[2] * t + p[3]) - y

    def fit_jac(p):
        e, c, s = np.exp(-p[1] * t), np.cos(p[2] * t + p[3]), np.sin(p[2] * t + p[3])
        return np.column_stack([e * c, -t * p[0] * e * c, -t * p[0] * e * s, -p[0] * e * s])

    p0 = np.array([1.5, 0.5, 2.8, 0.0])
    ours = levenberg_marquardt(fit, normal(fit_jac), p0)
    ref = least_squares(fit, p0, jac=fit_jac, method='trf', ftol=1e-14, xtol=1e-14, gtol=1e-14).x
    np.testing.assert_allclose(ours, ref, atol=1e-7)
    assert fit(ours) @ fit(ours) <= fit(ref) @ fit(ref) * (1 + 1e-12)


def test_the_closest_curves_normal_equations_are_those_of_its_residuals(monkeypatch, rounded_zigzag):
    """The closest curve forms J^T J and J^T r without stacking J (the penalty rows analytically): at the start and
    at the solution of a plan with active rate and cap penalties they match a finite-difference Jacobian of its
    residuals."""
    from rod_deploy.planning import curvature_rate
    seen = []
    solve = curvature_rate.levenberg_marquardt

    def spy(residuals, normal_equations, x0, **kw):
        x = solve(residuals, normal_equations, x0, **kw)
        seen.append((residuals, normal_equations, x0, x))
        return x

    monkeypatch.setattr(curvature_rate, 'levenberg_marquardt', spy)
    plan_trajectory(rounded_zigzag, ROD, PlannerSettings())
    residuals, normal_equations, x0, x1 = seen[0]
    # at the start and near the solution (which sits on the rate limit's hinge, where no finite difference holds)
    k = len(x0) - 1                                     # knots: rate (k - 1), cap (k), smoothing (k - 1) rows
    for x in (x0, x1 + 1e-3 * np.random.default_rng(0).standard_normal(len(x1))):
        r = residuals(x)
        assert np.count_nonzero(r[-(3 * k - 2):-(k - 1)]) > 0                # penalties active
        eps = 1e-7
        J = np.column_stack([(residuals(x + eps * e) - residuals(x - eps * e)) / (2 * eps) for e in np.eye(len(x))])
        A, g = normal_equations(x, residuals(x))
        np.testing.assert_allclose(A, J.T @ J, rtol=1e-5, atol=1e-5 * np.abs(J.T @ J).max())
        np.testing.assert_allclose(g, J.T @ r, rtol=1e-5, atol=1e-5 * np.abs(J.T @ r).max())
