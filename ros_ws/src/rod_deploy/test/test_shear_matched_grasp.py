"""Shear-matched grasps (suspended_rod kind 'shear', optimal_grasp.shear_matched_grasp): the grasp with a prescribed
lateral force at the connective node, and the physical limit on it (benchmarks/shear_matched_grasp.py)."""
import numpy as np
import pytest

from rod_deploy.planning.optimal_grasp import elastic_stability, optimal_grasp, shear_matched_grasp
from rod_deploy.planning.suspended_rod import SHEAR_RELEASES, BVPError, solve_suspended_rod


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
