"""robot_bridge.sim.arm_follower: the simulated arm follows commands, holds the clamped loop, and its sensors show
the switchable effects (bias, gain, delays) exactly as declared."""
from pathlib import Path

import numpy as np
import pytest

from robot_bridge.sim.arm_follower import ArmFollower
from robot_bridge.sim.experiment import load_experiment
from robot_bridge.sim.motion import SumOfSinesMotion, reference
from robot_bridge.sim.mujoco_loop import Effects

EXPERIMENT = Path(__file__).resolve().parents[4] / 'bags' / 'example_loop12' / 'experiment.yaml'
pytestmark = pytest.mark.skipif(not EXPERIMENT.exists(), reason='example experiment not in this checkout')


def test_follows_a_command_and_holds_the_last_point():
    f = ArmFollower(load_experiment(EXPERIMENT))
    q0, _ = f.state()
    target = q0 + np.array([0.1, -0.1, 0.1, 0.1, -0.1, 0.1, 0.2])
    f.command(np.array([0.5, 1.0]), np.array([q0 + 0.5 * (target - q0), target]))
    f.advance_to(0.5)
    assert np.max(np.abs(f.state()[0] - (q0 + 0.5 * (target - q0)))) < 5e-3
    f.advance_to(1.5)
    assert f.trajectory_done and np.max(np.abs(f.state()[0] - target)) < 1e-3


def test_holding_the_clamped_loop_keeps_the_welds_closed_and_loads_the_arm():
    exp = load_experiment(EXPERIMENT)
    held = ArmFollower(exp, with_object=True)
    free = ArmFollower(exp, q_start=held.state()[0])
    # at rest from the first sample on, the torque sensors included (not zero before the first step)
    tau_first = held.measure()[2]
    held.advance_to(0.5)
    assert np.max(np.abs(tau_first)) > 5.0 and np.allclose(held.measure()[2], tau_first, atol=1e-6)
    for f in (held, free):
        q0, _ = f.state()
        f.command(np.array([1.0, 2.0]), np.array([q0 + 0.05, q0]))
        f.advance_to(2.5)
    assert held.sim.weld_residual()[0] < 1e-5
    # the loop's weight and springs show in the measured torques (0.6 kg loop: at least 0.5 N m somewhere)
    assert np.max(np.abs(held.measure()[2] - free.measure()[2])) > 0.5


def test_excitation_is_the_example_motion_from_the_current_pose_started_when_asked():
    f = ArmFollower(load_experiment(EXPERIMENT))
    f.advance_to(0.3)
    q0, _ = f.state()
    motion = SumOfSinesMotion(amplitudes_rad=0.05)
    ex = f.excitation(6.0, motion)
    with pytest.raises(ValueError, match='shorter than'):
        f.excitation(5.0, motion)
    with pytest.raises(ValueError, match='limits of right_s0'):
        f.excitation(6.0, SumOfSinesMotion(amplitudes_rad=10.0))
    ex.t0_s = 0.5                                     # started later, as sim_arm does when a subscriber appears
    f.reference = ex
    f.advance_to(2.5)
    want = reference(np.array([2.0]), q0, 6.0, motion)[0][0]
    assert not np.allclose(want, q0, atol=1e-3) and np.max(np.abs(f.state()[0] - want)) < 2e-3
    f.advance_to(6.6)
    assert f.trajectory_done and np.max(np.abs(f.state()[0] - q0)) < 1e-3 and ex.t_end_s == 6.5


def test_sensor_effects_bias_gain_and_delays():
    exp = load_experiment(EXPERIMENT)
    f = ArmFollower(exp, effects=Effects(effort_bias_nm=0.5, effort_gain=1.1, position_delay_s=0.02,
                                         effort_delay_s=0.01))
    q0, _ = f.state()
    f.command(np.array([1.0]), np.array([q0 + 0.1]))
    f.advance_to(0.5)                          # moving: the delays matter
    q, qd, tau = f.measure()
    past_q = [h for h in f.history if abs(h[0] - (f.t_s - 0.02)) < 1e-9][0]
    past_tau = [h for h in f.history if abs(h[0] - (f.t_s - 0.01)) < 1e-9][0]
    assert np.allclose(q, past_q[1]) and not np.allclose(q, f.state()[0])
    assert np.allclose(tau, 1.1 * past_tau[3] + 0.5)
