"""Shear-matched grasps (suspended_rod kind 'shear', optimal_grasp.shear_matched_grasp): the grasp with a prescribed
lateral force at the connective node, the physical limit on it (benchmarks/shear_matched_grasp.py), and the
least-force grasp the planner can use (PlannerSettings.shear 'least_force')."""
import numpy as np
import pytest

from rod_deploy.deployment.metrics import eq17_error
from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment
from rod_deploy.planning.optimal_grasp import (closest_shear_grasp, elastic_stability, optimal_grasp,
                                               shear_matched_grasp)
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.suspended_rod import SHEAR_RELEASES, BVPError, solve_suspended_rod
from rod_deploy.planning.trajectory import PlannerSettings, PlanningError, plan_trajectory

#: e_mean bound of the short least-force deployment (measured 0.051 cm, the moment-free plan 0.060 cm)
BOUND_CM = 0.1


def _moment_balance(sol):
    """kappa_bvp - m_z(ls) - (x_g n0_y - y_g n0_x): zero for any solution (moment about the vertical through q_C)."""
    n0, q = sol.Y[0, 9:12], sol.gripper_position
    return sol.Y[0, 8] - sol.Y[-1, 8] - (q[0] * n0[1] - q[1] * n0[0])


@pytest.mark.parametrize('release,ls', [('gripper_out_of_plane', 3.0), ('gripper_in_plane', 3.0),
                                        ('tangential', 3.0), ('tangential', 12.0)])
def test_reproduces_the_moment_free_grasp_at_its_own_lateral_force(release, ls):
    free = optimal_grasp(ls, 0.5, np.inf, check_stability=False)
    n0y = float(free.solution.Y[0, 10])
    sol = solve_suspended_rod('shear', ls, np.inf, free.solution.kappa_bar, guess=free.solution, s=free.solution.s,
                              lateral_force=n0y, shear_release=release)
    assert np.max(np.abs(sol.Y - free.solution.Y)) < 1e-6
    assert np.linalg.norm(sol.m[-1]) < 1e-8                  # the gripper stays moment free there


@pytest.mark.parametrize('release,ls', [('gripper_out_of_plane', 3.0), ('gripper_in_plane', 1.5),
                                        ('tangential', 12.0)])
def test_applies_the_prescribed_lateral_force(release, ls):
    free = optimal_grasp(ls, 0.5, np.inf, check_stability=False)
    g, _ = shear_matched_grasp(ls, 0.5, np.inf, 0.0, release=release, moment_free=free)
    sol = g.solution
    assert abs(sol.Y[0, 10]) < 1e-9                          # n0_y = 0: the laid circle's shear
    assert g.clamp_force[1] == pytest.approx(0.0, abs=1e-9)
    assert sol.Y[0, 8] == pytest.approx(-0.5, abs=1e-9)       # the pattern's moment at q_C (released sign)
    assert abs(sol.Y[0, 7]) < 1e-9 and g.force_residual < 1e-7
    assert abs(_moment_balance(sol)) < 1e-6
    if release == 'tangential':
        assert np.linalg.norm(sol.m[-1]) < 1e-8              # moment free, the tangential force pays for it:
        assert sol.Y[0, 9] == pytest.approx(0.5 / sol.gripper_position[1], rel=1e-5)   # kappa = -y_g n0_x
        assert abs(sol.Y[0, 9]) > abs(free.solution.Y[0, 10])   # a larger horizontal force than the free n0_y
    else:
        assert abs(sol.Y[0, 9]) < 1e-9
        assert np.linalg.norm(sol.m[-1]) > 0.3                # the gripper supplies a moment


def test_clamped_gripper_grasp_is_stable_at_short_suspended_length():
    free = optimal_grasp(1.5, 0.5, np.inf, check_stability=False)
    g, _ = shear_matched_grasp(1.5, 0.5, np.inf, 0.0, release='gripper_out_of_plane', moment_free=free,
                               check_stability=True)
    assert g.stable is True


def test_gripper_moment_cannot_move_the_lateral_force_of_a_vertical_hanging_rod():
    """ls_bar 25: the hanging part is vertical and twist free, it carries no moment about the vertical, so
    kappa = x_g n0_y whatever the gripper does: the gripper-moment family is singular (Newton cannot move n0_y)."""
    free = optimal_grasp(25.0, 0.5, np.inf, check_stability=False)
    n0y = float(free.solution.Y[0, 10])
    with pytest.raises(BVPError):
        shear_matched_grasp(25.0, 0.5, np.inf, 0.5 * n0y, release='gripper_out_of_plane', moment_free=free,
                            min_step=1e-3)
    assert free.solution.Y[0, 10] * free.solution.gripper_position[0] == pytest.approx(-0.5, rel=1e-6)


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError):
        solve_suspended_rod('optimal', 3.0, np.inf, 0.5, lateral_force=0.1)
    with pytest.raises(ValueError):
        solve_suspended_rod('shear', 3.0, np.inf, 0.5)
    with pytest.raises(ValueError):
        shear_matched_grasp(3.0, 0.5, np.inf, 0.0, release='twist')
    with pytest.raises(ValueError):
        shear_matched_grasp(3.0, 0.5, np.inf, np.nan)
    assert set(SHEAR_RELEASES) == {'gripper_out_of_plane', 'gripper_in_plane', 'tangential'}


# ------------------------------------------------------------------ the least-force grasp and the planner option
@pytest.mark.parametrize('kappa_bar,floor', [(1.0, 0.45), (0.5, 0.205)])
def test_least_force_grasp_lowers_the_horizontal_force_at_the_connective_node(kappa_bar, floor):
    # benchmarks/results/shear_matched_grasp.md section 4: 0.567 -> 0.419 (kappa_bar 1), 0.217 -> 0.199 (0.5)
    free = optimal_grasp(12.0, kappa_bar, np.inf, check_stability=False)
    g, _ = closest_shear_grasp(12.0, kappa_bar, np.inf, 0.0, moment_free=free)
    n_free, n = free.solution.Y[0, 9:11], g.solution.Y[0, 9:11]
    assert abs(n_free[0]) < 1e-9
    assert np.hypot(*n) < floor < np.hypot(*n_free)
    assert np.linalg.norm(g.solution.m[-1]) < 1e-8                      # the gripper stays moment free
    assert g.solution.Y[0, 8] == pytest.approx(-kappa_bar, abs=1e-9)     # the pattern's moment at q_C
    assert abs(_moment_balance(g.solution)) < 1e-6
    assert elastic_stability(g.solution)['stable'] is True


def test_least_force_grasp_of_a_straight_pattern_is_the_moment_free_one():
    free = optimal_grasp(12.0, 0.0, np.inf, check_stability=False)
    g, _ = closest_shear_grasp(12.0, 0.0, np.inf, 0.0, moment_free=free)
    assert g is free


def test_planner_refuses_a_prescribed_shear_without_the_numeric_solver():
    with pytest.raises(PlanningError, match='numeric'):
        PlannerSettings(method='nn', shear='least_force').validate()
    with pytest.raises(PlanningError, match='shear'):
        PlannerSettings(method='numeric', shear='twisted').validate()


def test_short_least_force_deployment_is_laid_in_our_der():
    # a 0.3 m rod (#3's L_gb): 5 cm straight, then 7 cm of an arc of radius 8 cm (test_correction.py's pattern)
    rod = rod_description_from_dict({'length': 0.3, 'radius': 0.002, 'L_gb': 0.034, 'friction': 0.5})
    a = np.linspace(0.0, 0.07 / 0.08, 30)
    pattern = np.vstack([np.column_stack([np.linspace(0, 0.05, 11)[:-1], np.zeros(10)]),
                         np.column_stack([0.05 + 0.08 * np.sin(a), 0.08 * (1 - np.cos(a))])])
    fast = SimulationSettings(edge_length_m=0.01, dt_s=0.1, max_gripper_speed_m_s=0.03, contact_tolerance_m=5e-4)
    plan = plan_trajectory(pattern, rod, PlannerSettings(method='numeric', shear='least_force'))
    free = plan_trajectory(pattern, rod, PlannerSettings(method='numeric'))
    assert np.max(np.abs(plan.grasp_position - free.grasp_position)) > 1e-3    # the grasps did change
    res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod, fast)
    assert eq17_error(pattern, res.deployed_xy)['e_mean_cm'] < BOUND_CM


def test_cli_plan_shear_flag(tmp_path, capsys):
    import json

    from rod_deploy.cli.main import main as cli
    rod = tmp_path / 'rod.yaml'
    rod.write_text('length: 0.3\nradius: 0.002\nL_gb: 0.034\nfriction: 0.5\n')
    pts = tmp_path / 'p.txt'
    a = np.linspace(0.0, 0.07 / 0.08, 30)                # 5 cm straight, then 7 cm of an arc of radius 8 cm
    np.savetxt(pts, np.vstack([np.column_stack([np.linspace(0, 0.05, 11)[:-1], np.zeros(10)]),
                               np.column_stack([0.05 + 0.08 * np.sin(a), 0.08 * (1 - np.cos(a))])]))
    out = tmp_path / 't.csv'
    assert cli(['plan', '--pattern', str(pts), '--rod', str(rod), '--shear', 'least_force', '--out', str(out)]) == 2
    assert 'numeric' in capsys.readouterr().err and not out.exists()
    assert cli(['plan', '--pattern', str(pts), '--rod', str(rod), '--method', 'numeric', '--shear', 'least_force',
                '--quiet', '--out', str(out)]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])['shear'] == 'least_force' and out.exists()
