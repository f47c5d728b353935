"""The friction-limited ('achievable') start of a pattern: the closed-form curvature bound, a pattern within it left
alone, a circle from its first point (curvature at the free end) replaced by the closest curve within the bound that
rejoins the circle exactly, and the planner option."""
from dataclasses import replace

import numpy as np
import pytest

from rod_deploy.planning.achievable_start import (achievable_start, friction_curvature_limit,
                                                  friction_moment_capacity_m2, start_length_needed_m)
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, PlanningError, plan_trajectory, process_pattern

LGB, MU = 0.034, 0.5
ROD = rod_description_from_dict({'length': 0.6, 'radius': 0.002, 'L_gb': LGB, 'friction': MU})


def arc(radius_m, turn_rad, n=300):
    th = np.linspace(0.0, turn_rad, n)
    return np.column_stack([radius_m * np.sin(th), radius_m * (1.0 - np.cos(th))])


def test_curvature_bound_is_the_pure_friction_moment_over_EI():
    # EI kappa = mu rho A g s^2 / 4 (a moment with no net force) with EI = 2 rho A g L_gb^3
    s = np.array([0.0, 0.02, 0.05])
    np.testing.assert_allclose(friction_curvature_limit(s, LGB, MU), MU * s ** 2 / 4 / (2 * LGB ** 3))
    # the start length needed for kappa_bar is where the bound reaches it
    kb = 0.47
    ell = start_length_needed_m(kb, LGB, MU)
    assert friction_curvature_limit(ell, LGB, MU) * LGB == pytest.approx(kb, rel=1e-12)
    assert friction_curvature_limit(ell, LGB, MU, share=0.5) * LGB == pytest.approx(kb / 2, rel=1e-12)


def test_friction_moment_capacity_against_a_linear_programme():
    # the largest moment sum f_i y_i dy of |f_i| <= 1 on y in [-s, 0] with a net force F = M / lever, by linprog
    from scipy.optimize import linprog
    s, n = 0.05, 2000
    y = -s + (np.arange(n) + 0.5) * s / n
    for lever in (0.01, 0.085, 1e3):
        res = linprog(-y * s / n, A_eq=[(lever - y) * s / n], b_eq=[0.0], bounds=[(-1.0, 1.0)] * n,
                      method='highs')
        assert friction_moment_capacity_m2(s, lever) == pytest.approx(-res.fun, rel=2e-3)
    # a pure moment (lever -> infinity): s^2 / 4; the sideways force lowers it
    assert friction_moment_capacity_m2(s, 1e3) == pytest.approx(s ** 2 / 4, rel=1e-4)
    assert friction_moment_capacity_m2(s, 0.085) < 0.8 * s ** 2 / 4


def test_a_pattern_within_the_bound_is_unchanged():
    line = process_pattern(np.column_stack([np.linspace(0, 0.3, 50), np.zeros(50)]))
    assert achievable_start(line, LGB, MU) is line


def test_a_curved_start_is_replaced_by_the_closest_holdable_curve():
    radius = 0.1                                     # kappa_bar = 0.34 from the very first point
    pattern = process_pattern(arc(radius, 1.6 * np.pi))
    out = achievable_start(pattern, LGB, MU)
    kmax = friction_curvature_limit(out.s, LGB, MU)
    assert np.all(np.abs(out.kappa) <= kmax + 0.01 / LGB)     # within the bound (to the penalty's tolerance)
    np.testing.assert_allclose(out.xy[0], pattern.xy[0], atol=1e-12)      # the free end stays at P(0)
    np.testing.assert_allclose(np.linalg.norm(out.tangent, axis=1), 1.0, atol=1e-12)
    np.testing.assert_array_equal(out.s, pattern.s)
    # beyond the corrected stretch the pattern itself, and the curve arrives there continuously
    changed = np.flatnonzero(np.any(out.xy != pattern.xy, axis=1))
    tail = changed[-1] + 1
    assert pattern.s[tail] < 0.5 * pattern.length
    np.testing.assert_array_equal(out.xy[tail:], pattern.xy[tail:])
    step = np.linalg.norm(np.diff(out.xy, axis=0), axis=1)
    assert np.all(np.abs(step - pattern.s[1]) < 0.3e-3)
    assert np.degrees(np.arccos(np.clip(out.tangent[tail - 1] @ pattern.tangent[tail - 1], -1, 1))) < 2.0
    # closer to the pattern than what the rod lays from a tangent start (the clipped curvature, no correction)
    dev = np.linalg.norm(out.xy - pattern.xy, axis=1)
    th = np.concatenate([[0.0], np.cumsum(np.clip(pattern.kappa, -kmax, kmax)[:-1] * np.diff(pattern.s))])
    laid = np.column_stack([np.cumsum(np.cos(th)), np.cumsum(np.sin(th))]) * pattern.s[1] - [pattern.s[1], 0]
    dev_laid = np.linalg.norm(laid - pattern.xy, axis=1)
    assert dev.mean() < 0.2 * dev_laid.mean()
    assert dev.max() < 8e-3          # 6.7 mm: a 10 cm radius from its first point, c mu = 0.5


def test_planner_option_is_the_default_and_leaves_a_straight_start_alone():
    assert PlannerSettings().start == 'achievable'
    straight = np.column_stack([np.linspace(0.0, 0.3, 61), np.zeros(61)])
    a = plan_trajectory(straight, ROD)
    b = plan_trajectory(straight, ROD, PlannerSettings(start='tangent'))
    np.testing.assert_array_equal(a.pattern.xy, b.pattern.xy)
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.quaternion, b.quaternion)
    pts = arc(0.1, np.pi)
    # without the drag compensation, whose template (moved within the start too) may be a node longer
    plain = plan_trajectory(pts, ROD, PlannerSettings(start='tangent', drag_compensation=False))
    plan = plan_trajectory(pts, ROD, PlannerSettings(drag_compensation=False))
    assert plain.pattern.xy.shape == plan.pattern.xy.shape
    np.testing.assert_allclose(plan.position[0, :2], plan.pattern.xy[0], atol=1e-12)   # hanging above its start
    held = plan_trajectory(pts, ROD, PlannerSettings(free_start_point=False))
    np.testing.assert_allclose(held.pattern.xy[0], pts[0], atol=2e-4)                 # held: P(0)
    assert np.max(np.abs(plan.pattern.xy - plain.pattern.xy)) > 1e-4          # the start was changed
    with pytest.raises(PlanningError, match='start'):
        plan_trajectory(pts, ROD, PlannerSettings(start='curved'))
    with pytest.raises(PlanningError, match='friction_share'):
        plan_trajectory(pts, ROD, PlannerSettings(start='achievable', friction_share=0.0))
    with pytest.raises(PlanningError, match=r'friction_share must be in \(0, 2\], got 2.5'):
        plan_trajectory(pts, ROD, PlannerSettings(friction_share=2.5))


def test_a_share_above_one_lets_the_start_bend_more():
    # c = 1.5: the start follows the pattern's curvature earlier, beyond what c = 1 allows but within its own bound
    pattern = process_pattern(arc(0.1, 1.6 * np.pi))
    one, more = achievable_start(pattern, LGB, MU, 1.0), achievable_start(pattern, LGB, MU, 1.5)
    kmax = friction_curvature_limit(pattern.s, LGB, MU)
    assert np.max(np.abs(more.kappa) - kmax) * LGB > 0.02
    assert np.all(np.abs(more.kappa) <= 1.5 * kmax + 0.01 / LGB)
    dev = [np.mean(np.linalg.norm(p.xy - pattern.xy, axis=1)) for p in (one, more)]
    assert dev[1] < 0.8 * dev[0]
    plan = plan_trajectory(arc(0.1, 1.6 * np.pi), ROD, PlannerSettings(friction_share=2.0))   # accepted
    assert np.max(np.abs(plan.position[:, :2] - plan_trajectory(arc(0.1, 1.6 * np.pi), ROD).position[:, :2])) > 1e-4


def test_cli_plan_start_option(tmp_path, capsys):
    import json

    from rod_deploy.cli.main import main as cli
    from rod_deploy.planning.trajectory_io import read_trajectory_csv
    pattern = tmp_path / 'arc.txt'
    np.savetxt(pattern, arc(0.1, np.pi))
    rod = tmp_path / 'rod.yaml'
    rod.write_text('length: 0.6\nradius: 0.002\nL_gb: 0.034\nfriction: 0.5\n')
    outs = {}
    for start in ('tangent', 'achievable', None):
        out = tmp_path / f'{start}.csv'
        assert cli(['plan', '--pattern', str(pattern), '--rod', str(rod), '--out', str(out)]
                   + (['--start', start] if start else [])) == 0
        assert json.loads(capsys.readouterr().out)['start'] == (start or 'achievable')
        outs[start] = read_trajectory_csv(out)
    np.testing.assert_array_equal(outs[None][1], outs['achievable'][1])      # the default start
    a, b = outs['tangent'], outs['achievable']
    assert abs(len(a[0]) - len(b[0])) <= 1              # the drag compensation's templates: a node longer or not
    np.testing.assert_allclose(a[1][0, 2], b[1][0, 2], atol=1e-9)      # both start at the hanging pose, the
    assert np.linalg.norm(a[1][0, :2] - b[1][0, :2]) < 0.01             # achievable one a few mm off P(0)
    n = min(len(a[1]), len(b[1]))
    assert np.max(np.abs(a[1][:n] - b[1][:n])) > 1e-4                   # a different start


def test_looser_start_where_the_bound_keeps_the_plan_far_from_the_pattern():
    # a half circle of 10 cm radius from its first point: within c = 1 the planned curve stays 2.1 mm from it on
    # average; counting on 1.5 times the share brings it within 1.2 mm, more than LOOSER_START_GAIN_M nearer
    from rod_deploy.planning.trajectory import LOOSER_START_FACTOR, LOOSER_START_GAIN_M
    pts = arc(0.1, np.pi)
    plan = plan_trajectory(pts, ROD)
    fixed = plan_trajectory(pts, ROD, PlannerSettings(looser_start=False))
    assert PlannerSettings().looser_start
    assert fixed.friction_share == 1.0
    assert plan.friction_share == LOOSER_START_FACTOR

    def mean_distance(settings):           # the planned curve's, before the drag compensation moves the template
        p = plan_trajectory(pts, ROD, replace(settings, drag_compensation=False))
        return np.mean(np.linalg.norm(p.asked_xy - p.drawn_pattern.xy, axis=1))
    assert mean_distance(PlannerSettings()) < mean_distance(PlannerSettings(looser_start=False)) - LOOSER_START_GAIN_M
    # the same plan as asking for that share outright
    np.testing.assert_array_equal(plan.position, plan_trajectory(pts, ROD, PlannerSettings(
        friction_share=LOOSER_START_FACTOR, looser_start=False)).position)
    # a gently bent start (radius 20 cm) gains less: the estimate stands, the plan as before
    gentle = arc(0.2, 0.5 * np.pi)
    a, b = plan_trajectory(gentle, ROD), plan_trajectory(gentle, ROD, PlannerSettings(looser_start=False))
    assert a.friction_share == 1.0
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.quaternion, b.quaternion)
    # below LOOSER_START_MIN_FRICTION the estimate stands (at 0.45 the looser start would be taken here too)
    assert plan_trajectory(pts, ROD, PlannerSettings(friction=0.45)).friction_share == 1.0
    # no start to loosen: the tangent start and the intuitive baseline report none
    assert plan_trajectory(pts, ROD, PlannerSettings(start='tangent')).friction_share is None
    assert plan_trajectory(pts, ROD, PlannerSettings(method='intuitive')).friction_share is None


def test_cli_plan_no_looser_start(tmp_path, capsys):
    import json

    from rod_deploy.cli.main import main as cli
    np.savetxt(tmp_path / 'arc.txt', arc(0.1, np.pi))
    (tmp_path / 'rod.yaml').write_text('length: 0.6\nradius: 0.002\nL_gb: 0.034\nfriction: 0.5\n')
    shares = []
    for extra in ([], ['--no-looser-start']):
        assert cli(['plan', '--pattern', str(tmp_path / 'arc.txt'), '--rod', str(tmp_path / 'rod.yaml'),
                    '--out', str(tmp_path / 't.csv'), *extra]) == 0
        shares.append(json.loads(capsys.readouterr().out)['start_friction_share'])
    assert shares == [1.5, 1.0]
