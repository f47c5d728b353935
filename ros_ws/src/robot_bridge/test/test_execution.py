"""The executed gripper path from measured joint states: the command's start is recovered on the measurement clock
(whatever the first guess), the path is the forward kinematics at the commanded points, bad data is refused."""
import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from robot_bridge.kinematics.execution import ExecutionError, executed_gripper_path, joint_matrix, path_deviation_m
from robot_bridge.kinematics.planner import ArmCommandPlanner, BridgeConfig
from robot_bridge.sim.motion import BAXTER_RIGHT_NOMINAL_RAD


def command_and_measurement(s0_true, rate_hz=100.0, noise_rad=0.0):
    """A smooth 3 s joint motion commanded at 30 points 1 s after the start; measured from 0 to s0 + 5 s."""
    q0 = np.array(BAXTER_RIGHT_NOMINAL_RAD)
    tfs = 1.0 + np.linspace(0.0, 3.0, 30)
    amplitude = np.linspace(0.1, 0.3, len(q0))
    q_of = CubicSpline([0.0, 1.0, 2.5, 4.0, 6.0], [q0, q0, q0 + amplitude, q0 - amplitude, q0 - amplitude],
                       bc_type='clamped')
    stamps = np.arange(0.0, s0_true + 5.0, 1.0 / rate_hz) + 100.0     # any clock origin
    q_meas = q_of(np.clip(stamps - 100.0 - s0_true, 0.0, None))
    q_meas += np.random.default_rng(0).normal(0.0, noise_rad, q_meas.shape)
    return tfs, q_of(tfs), stamps, q_meas


@pytest.mark.parametrize('guess_error_s', [0.0, -0.8])
def test_the_start_is_recovered_and_the_path_is_the_forward_kinematics(guess_error_s):
    planner = ArmCommandPlanner(BridgeConfig())
    s0 = 0.537
    tfs, q_cmd, stamps, q_meas = command_and_measurement(s0, noise_rad=1e-4)
    executed = executed_gripper_path(planner, stamps, q_meas, tfs, q_cmd, 100.0 + s0 + guess_error_s)
    assert abs(executed.start_stamp_s - (100.0 + s0)) < 2e-3
    assert executed.joint_rms_rad < 5e-4 and abs(executed.samples_used - 300) <= 1     # 3 s at 100 Hz
    planned = planner.executed_path(tfs - tfs[0], q_cmd)         # the commanded joints' gripper path
    assert path_deviation_m(executed.path, planned)['max_m'] < 1e-3
    assert np.allclose(executed.path.t_s, tfs - tfs[0])


def test_measurements_that_do_not_cover_the_command_are_refused():
    planner = ArmCommandPlanner(BridgeConfig())
    tfs, q_cmd, stamps, q_meas = command_and_measurement(0.5)
    keep = stamps < 102.0                                       # ends before the command does
    with pytest.raises(ExecutionError, match='before the command does'):
        executed_gripper_path(planner, stamps[keep], q_meas[keep], tfs, q_cmd, 100.5)
    with pytest.raises(ExecutionError, match='do not increase'):
        executed_gripper_path(planner, stamps[::-1], q_meas, tfs, q_cmd, 100.5)


def test_joint_matrix_orders_by_name_and_refuses_a_missing_joint():
    q = joint_matrix([['b', 'a'], ['a', 'b']], [[2.0, 1.0], [3.0, 4.0]], ['a', 'b'])
    assert np.array_equal(q, [[1.0, 2.0], [3.0, 4.0]])
    with pytest.raises(ExecutionError, match="lacks joint"):
        joint_matrix([['a']], [[1.0]], ['a', 'b'])
