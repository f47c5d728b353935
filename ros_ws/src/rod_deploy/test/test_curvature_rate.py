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


def test_a_start_share_above_one_refuses_what_share_one_refuses():
    # the refusal counts on min(c, 1) of the friction: a 9 cm lead into a 3 cm curl (kappa_bar 1.13, the check's
    # limit at 9 cm 0.91 with c = 1, 1.56 with c = 2) is refused whatever share the start plans with (counting on
    # c = 2 there would plan it)
    for share in (1.0, 1.5, 2.0):
        with pytest.raises(PlanningError, match='cannot hold'):
            plan_trajectory(lead_then_curl(0.09, 0.03), ROD, PlannerSettings(friction_share=share))
    plan_trajectory(lead_then_curl(0.10, 0.03), ROD, PlannerSettings(friction_share=2.0))     # a longer lead holds


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
    # the hanging pose above its first point; the start point held (the default): on the pattern. Fitting the start
    # point too lowers the fit's sum of squares but not the zig-zag's mean distance: the held one is kept (nearer)
    np.testing.assert_allclose(closest.position[0, :2], c.xy[0], atol=1e-12)
    np.testing.assert_allclose(c.xy[0], given.xy[0], atol=1e-9)
    free = plan_trajectory(pts, ROD, PlannerSettings(free_start_point=True, drag_compensation=False))
    np.testing.assert_allclose(free.pattern.xy, c.xy, atol=1e-12)
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
    # the tolerance matters: stopped at a loose one it is not there
    assert np.abs(levenberg_marquardt(fit, normal(fit_jac), p0, ftol=1e-3) - ref).max() > 1e-7

    # with bounds |x_i| <= b_i kept as penalty rows w max(|x_i| - b_i, 0) (the amplitude held below its fit's 2):
    # the minimum of the residuals stacked with those rows, to which scipy runs from the same start
    b, w = np.array([1.6, np.inf, np.inf, 0.3]), 30.0

    def stacked(p):
        return np.concatenate([fit(p), w * np.maximum(np.abs(p) - b, 0.0)])

    def stacked_jac(p):
        return np.vstack([fit_jac(p), np.diag(w * (np.abs(p) > b) * np.sign(p))])

    bounded = levenberg_marquardt(fit, normal(fit_jac), p0, limits=(np.eye(4), b, w))
    ref = least_squares(stacked, p0, jac=stacked_jac, method='trf', ftol=1e-15, xtol=1e-15, gtol=1e-15).x
    assert abs(ref[0]) > b[0] and abs(ref[3]) > b[3]                        # both penalties active there
    np.testing.assert_allclose(bounded, ref, atol=1e-7)
    assert stacked(bounded) @ stacked(bounded) <= stacked(ref) @ stacked(ref) * (1 + 1e-12)
    assert np.abs(levenberg_marquardt(fit, normal(fit_jac), p0, limits=(np.eye(4), b, w), ftol=1e-3) - ref).max() > 1e-7
    with pytest.raises(ValueError, match='limits'):
        levenberg_marquardt(fit, normal(fit_jac), p0, limits=(np.eye(4), b[:3], w))


def test_levenberg_marquardt_with_coupled_limits_reaches_the_penalised_minimum():
    """Limits on differences of unknowns (the closest curve's rate limit: |x_i+1 - x_i| <= c) coupled with bounds,
    many of them active at the minimum: the solver ends where scipy's least_squares on the residuals stacked with
    the penalty rows ends (run to tight tolerances), in fewer Jacobians than the same problem handed to it with the
    penalties as residual rows (its active-set step keeps the Gauss-Newton model right across their hinges)."""
    from scipy.optimize import least_squares
    t = np.linspace(0.0, 1.0, 120)
    knots = np.linspace(0.0, 1.0, 25)
    hat = np.clip(1.0 - np.abs(t[:, None] - knots[None, :]) / (knots[1] - knots[0]), 0.0, None)
    target = np.sin(9.0 * t) + 0.5 * np.sign(np.sin(4.0 * t))           # steps the rate limit cannot follow

    def fit(x):
        return np.concatenate([np.tanh(hat @ x) - np.tanh(target), 0.05 * np.diff(x)])

    def fit_jac(x):
        return np.vstack([(1.0 - np.tanh(hat @ x) ** 2)[:, None] * hat, 0.05 * np.diff(np.eye(len(x)), axis=0)])

    D = np.vstack([np.eye(25), np.diff(np.eye(25), axis=0)])
    c = np.r_[np.full(25, 1.2), np.full(24, 0.25)]
    w = 40.0

    def stacked(x):
        return np.concatenate([fit(x), w * np.maximum(np.abs(D @ x) - c, 0.0)])

    def stacked_jac(x):
        return np.vstack([fit_jac(x), w * ((np.abs(D @ x) > c) * np.sign(D @ x))[:, None] * D])

    calls = {'limits': 0, 'rows': 0}

    def normal(jac, key):
        def ne(x, r):
            calls[key] += 1
            return jac(x).T @ jac(x), jac(x).T @ r
        return ne

    x0 = np.zeros(25)
    ours = levenberg_marquardt(fit, normal(fit_jac, 'limits'), x0, limits=(D, c, w), ftol=1e-13)
    ref = least_squares(stacked, x0, jac=stacked_jac, method='trf', ftol=1e-15, xtol=1e-15, gtol=1e-15).x
    assert np.sum(np.abs(D @ ref) > c) >= 5                                  # cap and rate rows active there
    assert stacked(ours) @ stacked(ours) <= stacked(ref) @ stacked(ref) * (1 + 1e-10)
    np.testing.assert_allclose(ours, ref, atol=1e-5)
    as_rows = levenberg_marquardt(stacked, normal(stacked_jac, 'rows'), x0, ftol=1e-13)
    np.testing.assert_allclose(as_rows, ref, atol=1e-5)
    assert calls['limits'] < calls['rows']



def test_the_compiled_cholesky_solves_and_flags_a_matrix_that_is_not_positive_definite():
    from rod_deploy.planning.closest_curve_kernel import cholesky_solve
    rng = np.random.default_rng(9)
    J = rng.normal(size=(300, 150))
    H, b = J.T @ J + 1e-3 * np.eye(150), rng.normal(size=150)
    x, ok = cholesky_solve(H, b)
    assert ok
    np.testing.assert_allclose(H @ x, b, atol=1e-9)
    np.testing.assert_allclose(x, np.linalg.solve(H, b), rtol=1e-8, atol=1e-10)
    H[70, 70] = -1.0                                                    # indefinite
    assert not cholesky_solve(H, b)[1]
    assert not cholesky_solve(np.full((3, 3), np.nan), np.ones(3))[1]


def test_levenberg_marquardt_hands_nothing_to_lapack(monkeypatch):
    """The steps' linear solves stay out of LAPACK: OpenBLAS's threads, woken by a Cholesky of more than about a hundred
    unknowns (rod #1's closest curve on a 0.7 m pattern), spun on the loaded 2-core machine and made `rod-deploy plan`
    of the fresh rehearsal's cursive m take 10.9 s of CPU (1.4 s without them)."""
    import scipy.linalg

    def refuse(*args, **kwargs):
        raise AssertionError('a LAPACK call in the solver loop')
    monkeypatch.setattr(np.linalg, 'cholesky', refuse)
    monkeypatch.setattr(np.linalg, 'solve', refuse)
    monkeypatch.setattr(scipy.linalg, 'cho_solve', refuse)
    monkeypatch.setattr(scipy.linalg, 'cho_factor', refuse)
    t = np.linspace(0.0, 1.0, 400)
    knots = np.linspace(0.0, 1.0, 150)
    hat = np.clip(1.0 - np.abs(t[:, None] - knots[None, :]) / (knots[1] - knots[0]), 0.0, None)
    target = np.sin(7.0 * t)

    def fit(x):
        return np.concatenate([np.tanh(hat @ x) - np.tanh(target), 0.05 * np.diff(x)])

    def fit_jac(x):
        return np.vstack([(1.0 - np.tanh(hat @ x) ** 2)[:, None] * hat, 0.05 * np.diff(np.eye(len(x)), axis=0)])

    x = levenberg_marquardt(fit, lambda x, r: (fit_jac(x).T @ fit_jac(x), fit_jac(x).T @ r), np.zeros(150),
                            limits=(np.eye(150), np.full(150, 0.9), 40.0))
    assert np.abs(np.tanh(hat @ x) - np.tanh(np.clip(target, -0.9, 0.9))).max() < 0.05

def test_the_fit_rows_normal_equations_by_recurrence_are_the_dense_products():
    """closest_curve_kernel forms J^T J and J^T r of the curve's points from d theta / d x without the dense
    (2 m, p) Jacobian: equal to the dense products to rounding, for columns that settle (a heading offset, knots of
    a piecewise linear curvature) and for one that never does."""
    from rod_deploy.planning.achievable_start import _cumtrapz
    from rod_deploy.planning.closest_curve_kernel import column_support, fit_normal_equations
    rng = np.random.default_rng(1)
    m = 90
    s = np.cumsum(np.r_[0.0, rng.uniform(0.5, 1.5, m - 1)]) * 0.004            # uneven steps
    theta = np.cumsum(rng.normal(0.0, 0.2, m))
    s_knots = np.linspace(0.0, s[-1], 14)
    hat = np.clip(1.0 - np.abs(s[:, None] - s_knots[None, :]) / (s_knots[1] - s_knots[0]), 0.0, None)
    ds = np.diff(s)
    dtheta = np.column_stack([np.ones(m), _cumtrapz(hat, ds) / LGB, np.sin(s / 0.05)])
    first, settled = column_support(dtheta)
    assert first[0] == 0 and settled[0] == 0 and settled[-1] == m - 1          # constant; never settles
    assert np.all(settled[1:-1] - first[1:-1] <= 16)       # the knots: their support, two spacings of 6.5 nodes
    half_ds = 0.5 * ds / LGB
    r = rng.normal(size=(m, 2))
    f = dtheta[:, :, None] * np.column_stack([-np.sin(theta), np.cos(theta)])[:, None, :]     # (m, p, 2)
    G = np.concatenate([np.zeros((1,) + f.shape[1:]), np.cumsum(half_ds[:, None, None] * (f[1:] + f[:-1]), axis=0)])
    J = G[1:].transpose(0, 2, 1).reshape(2 * (m - 1), -1)                    # rows (x_i, y_i), i >= 1
    A, g = fit_normal_equations(theta, dtheta, first, settled, half_ds, r)
    np.testing.assert_allclose(A, J.T @ J, rtol=1e-12, atol=1e-12 * np.abs(J.T @ J).max())
    np.testing.assert_allclose(g, J.T @ r[1:].ravel(), rtol=1e-12, atol=1e-12 * np.abs(g).max())


@pytest.mark.parametrize('free_start_point', [True, False])
def test_the_closest_curves_normal_equations_are_those_of_its_residuals(monkeypatch, rounded_zigzag,
                                                                          free_start_point):
    """The closest curve forms J^T J and J^T r without stacking J (the smoothing rows analytically): at the start and
    near the solution of a plan with active rate and cap limits they match a finite-difference Jacobian of its
    residuals, with the start point held and fitted (two unknowns after the knots)."""
    from rod_deploy.planning import curvature_rate
    seen = []
    solve = curvature_rate.levenberg_marquardt

    def spy(residuals, normal_equations, x0, **kw):
        x = solve(residuals, normal_equations, x0, **kw)
        seen.append((residuals, normal_equations, x0, x, kw))
        return x

    monkeypatch.setattr(curvature_rate, 'levenberg_marquardt', spy)
    plan_trajectory(rounded_zigzag, ROD, PlannerSettings(free_start_point=free_start_point, drag_compensation=False,
                                                         looser_start=False))
    # the last fit: with free_start_point the plan fits the curve held, then free (no drag compensation: it plans
    # twice; no looser start: it plans once more at 1.5 times the share)
    residuals, normal_equations, x0, x1, kw = seen[-1]
    assert len(seen) == 1 + free_start_point
    # the limits (the cap on each knot, the rate between neighbours) are the solver's: |D x| <= c, both active at
    # the solution; the residuals are the fit rows and the smoothing rows (k - 1 after the fit)
    D, c, _ = kw['limits']
    k = len(x0) - 1 - 2 * free_start_point
    active = np.abs(D @ x1) > c
    assert active[:k].any() and active[k:].any()                      # cap and rate limits active
    # at the start and near the solution (which sits on the rate limit's hinge)
    for x in (x0, x1 + 1e-3 * np.random.default_rng(0).standard_normal(len(x1))):
        r = residuals(x)
        eps = 1e-7
        J = np.column_stack([(residuals(x + eps * e) - residuals(x - eps * e)) / (2 * eps) for e in np.eye(len(x))])
        A, g = normal_equations(x, residuals(x))
        np.testing.assert_allclose(A, J.T @ J, rtol=1e-5, atol=1e-5 * np.abs(J.T @ J).max())
        np.testing.assert_allclose(g, J.T @ r, rtol=1e-5, atol=1e-5 * np.abs(J.T @ r).max())


def c_like_arc(radius_m=0.1, turn_rad=1.3 * np.pi, n=400):
    """An arc bent from its very first point, like the letter C (|kappa_bar| 0.34 on rod #3; the C: up to 0.5)."""
    th = np.linspace(0.0, turn_rad, n)
    return np.column_stack([radius_m * np.sin(th), radius_m * (1.0 - np.cos(th))])


def test_a_free_start_point_brings_a_curved_start_nearer_the_pattern_and_moves_the_hanging_pose_with_it():
    """Near the free end friction holds only kappa_max(s) ~ s^2, so a stroke bent from its first point must start
    nearly straight. Held at the pattern's first point, that straight start runs outside the bend; with the start
    point fitted too, the same bounded curve is put down a few millimetres inside it and straddles the pattern: it is
    nearer the pattern (Eq. 17 e_mean of the asked curve), keeps every limit, is one curve from its own first point,
    and the trajectory's hanging pose (where every simulator starts the free end) is above that point."""
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.deployment.simulate import replay_schedule
    from rod_deploy.planning.achievable_start import friction_curvature_limit, integrate_curvature
    pts = c_like_arc()
    # the planned curves for the pattern itself (no drag compensation: bend_drag.py's template is tested there), at
    # the start's share 1 (the looser start, test_achievable_start.py, brings the held one to 0.093 cm)
    held = plan_trajectory(pts, ROD, PlannerSettings(free_start_point=False, drag_compensation=False,
                                                     looser_start=False))
    free = plan_trajectory(pts, ROD, PlannerSettings(free_start_point=True, drag_compensation=False,
                                                     looser_start=False))
    assert not PlannerSettings().free_start_point       # the contract's start (the pattern's first point) by default
    given = free.drawn_pattern
    e_held = eq17_error(given.xy, held.asked_xy)['e_mean_cm']
    e_free = eq17_error(given.xy, free.asked_xy)['e_mean_cm']
    assert e_free < 0.8 * e_held                         # 0.162 -> 0.095 cm
    moved = np.linalg.norm(free.pattern.xy[0] - given.xy[0])
    assert 1e-3 < moved < 0.02                           # millimetres, not the pattern abandoned
    np.testing.assert_allclose(held.pattern.xy[0], given.xy[0], atol=1e-9)
    # the limits: the friction bound from the (new) free end and the rate limit
    kb = free.inputs[:, 2]
    assert np.all(np.abs(kb) <= friction_curvature_limit(given.s, LGB, 0.5) * LGB + 1e-9)
    assert np.abs(np.diff(kb)).max() <= default_max_rate(0.5) * STEP / LGB * 1.03
    c = free.pattern
    xy, _ = integrate_curvature(c.s, np.arctan2(c.tangent[0, 1], c.tangent[0, 0]), c.kappa, c.xy[0])
    np.testing.assert_allclose(xy, c.xy, atol=1e-9)
    np.testing.assert_allclose(free.asked_xy[0], c.xy[0], atol=1e-12)
    # the hanging pose (first pose: rod straight down) above the planned first point, the simulator's start there
    np.testing.assert_allclose(free.position[0, :2], c.xy[0], atol=1e-12)
    assert free.position[0, 2] == pytest.approx(ROD.hanging_height_m)
    sched = replay_schedule(free.t, free.position, free.quaternion, ROD)
    np.testing.assert_allclose(sched.start_xy, c.xy[0], atol=1e-12)
    # the lead-in runs from the hanging pose to the first grasp of the planned curve
    k = free.first_grasp_index
    assert np.linalg.norm(free.position[k, :2] - c.xy[0]) < np.linalg.norm(free.position[k, :2] - given.xy[0]) + 0.02


def test_the_free_start_point_refuses_nothing_the_held_one_accepts():
    """The friction check runs on the friction-limited start before the closest curve is fitted, so the start point's
    freedom neither refuses a pattern nor lets one through: a straight lead into a tight curl is refused both ways
    (named), a straight pattern is planned both ways with its start on the pattern."""
    for free in (True, False):
        with pytest.raises(PlanningError, match='cannot hold'):
            plan_trajectory(lead_then_curl(0.05, 0.016), ROD, PlannerSettings(free_start_point=free))
    line = np.column_stack([np.linspace(0.0, 0.4, 81), np.zeros(81)])
    plans = [plan_trajectory(line, ROD, PlannerSettings(free_start_point=f)) for f in (True, False)]
    for p in plans:
        np.testing.assert_allclose(p.pattern.xy[0], line[0], atol=1e-4)
