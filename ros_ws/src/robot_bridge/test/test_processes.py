"""The nodes as separate processes from their console scripts: record/replay, clean close on SIGINT and
SIGTERM, recovery after SIGKILL, and one clear error line for a bad bag."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from robot_bridge.bagio.contract import JointRecording, write_joint_recording
from robot_bridge.bagio.raw import iter_raw_messages
from robot_bridge.bagio.reindex import reindex_bag

BIN = os.path.dirname(sys.executable)


def make_bag(path, seconds, rate_hz=200):
    n = int(seconds * rate_hz)
    rng = np.random.default_rng(0)
    rec = JointRecording(np.arange(n) / rate_hz, ['a', 'b'], rng.normal(size=(n, 2)), None,
                         rng.normal(size=(n, 2)), stamp0_ns=1_000_000_000)
    write_joint_recording(path, rec)
    return [m.data for m in iter_raw_messages(path)]


def start(exe, *params):
    args = [os.path.join(BIN, exe), '--ros-args', '--log-level', 'warn']
    for p in params:
        args += ['-p', p]
    return subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_file(path, timeout=20):
    end = time.monotonic() + timeout
    while time.monotonic() < end and not os.path.exists(path):
        time.sleep(0.05)


@pytest.mark.parametrize('stop_signal', [signal.SIGINT, signal.SIGTERM])
def test_separate_processes_record_replay_and_close_cleanly(tmp_path, stop_signal):
    original = make_bag(tmp_path / 'in', seconds=2.0)
    logger = start('joint_state_logger', f'output:={tmp_path / "out"}', "topics:=['/joint_states']")
    player = start('bag_player', f'bag:={tmp_path / "in"}', 'wait_for_subscribers:=20.0')
    assert player.wait(timeout=60) == 0, player.stderr.read()
    time.sleep(2.0)          # the last messages in flight reach the logger (generous: a loaded machine is slow)
    logger.send_signal(stop_signal)
    assert logger.wait(timeout=20) == 0, logger.stderr.read()
    assert [m.data for m in iter_raw_messages(tmp_path / 'out')] == original


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_after_sigkill_everything_older_than_the_flush_period_is_recovered(tmp_path, storage):
    """The logger flushes at least every 0.5 s (README): after SIGKILL, reindex recovers everything received up to
    0.5 s before the kill, plus a margin of 0.1 s for the message in flight and the writer thread's wake-up."""
    original = make_bag(tmp_path / 'in', seconds=8.0)
    logger = start('joint_state_logger', f'output:={tmp_path / "out"}', "topics:=['/joint_states']", f'storage:={storage}')
    player = start('bag_player', f'bag:={tmp_path / "in"}', 'wait_for_subscribers:=20.0')
    wait_file(tmp_path / 'out')
    time.sleep(5.0)
    kill_ns = time.time_ns()
    logger.kill()
    logger.wait(timeout=10)
    player.kill()
    player.wait(timeout=10)
    recovered_n = reindex_bag(tmp_path / 'out')
    recovered = list(iter_raw_messages(tmp_path / 'out'))
    assert recovered_n == len(recovered) > 0
    assert [m.data for m in recovered] == original[:len(recovered)]   # a lossless prefix
    assert recovered[-1].timestamp_ns >= kill_ns - 600_000_000        # lost at most the flush period + margin
    assert (tmp_path / 'out.unindexed').exists()


def test_player_with_missing_bag_prints_one_error_line(tmp_path):
    player = start('bag_player', f'bag:={tmp_path / "nope"}')
    assert player.wait(timeout=30) == 1
    err = [line for line in player.stderr.read().splitlines() if line.strip()]
    assert len(err) == 1 and 'does not exist' in err[0]


def test_player_with_corrupt_bag_prints_one_error_line(tmp_path):
    make_bag(tmp_path / 'in', seconds=0.5)
    mcap = next((tmp_path / 'in').glob('*.mcap'))
    mcap.write_bytes(mcap.read_bytes()[:200])
    player = start('bag_player', f'bag:={tmp_path / "in"}', 'wait_for_subscribers:=0.0')
    assert player.wait(timeout=30) == 1
    err = [line for line in player.stderr.read().splitlines() if line.strip()]
    assert len(err) == 1 and 'error' in err[0], err


@pytest.mark.parametrize('stop_signal', [signal.SIGINT, signal.SIGTERM])
def test_player_stopped_mid_replay_exits_cleanly(tmp_path, stop_signal, ros_context, wait_for):
    from rclpy.node import Node
    from sensor_msgs.msg import JointState
    make_bag(tmp_path / 'in', seconds=20.0)
    observer = ros_context.add(Node('observer', context=ros_context.context))
    received = []
    observer.create_subscription(JointState, '/joint_states', received.append, 10)
    player = start('bag_player', f'bag:={tmp_path / "in"}', 'wait_for_subscribers:=20.0')
    # mid-replay for sure: the observer has received messages (a fixed sleep raced the start-up on a loaded machine)
    assert wait_for(lambda: len(received) > 0 or player.poll() is not None, timeout_s=60) and player.poll() is None
    player.send_signal(stop_signal)
    assert player.wait(timeout=20) == 0
    err = player.stderr.read()
    assert 'Traceback' not in err and 'RCLError' not in err and 'context is invalid' not in err, err
    assert 'stopped after' in err


def test_sim_arm_and_bridge_as_processes_execute_a_csv_path(tmp_path, ros_context, wait_for):
    """sim_arm and arm_command_bridge (trajectory_csv) started from their console scripts; this process watches
    the bridge's status and /joint_states until the arm's gripper reaches the path's last pose."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    from robot_bridge.kinematics.example_paths import deployment_like_path
    from robot_bridge.kinematics.gripper_path import write_gripper_csv
    from robot_bridge.kinematics.planner import ArmCommandPlanner, BridgeConfig

    path = deployment_like_path(n_poses=10, duration_s=1.0, radius_m=0.05, height_m=(0.35, 0.4), max_tilt_rad=0.2)
    write_gripper_csv(tmp_path / 'g.csv', path)
    planner = ArmCommandPlanner(BridgeConfig())
    goal = planner.to_base(path)[-1, :3, 3]
    observer = ros_context.add(Node('observer', context=ros_context.context))
    statuses, latest = [], {}
    observer.create_subscription(DiagnosticArray, '/arm_command_bridge/status', statuses.append, QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    observer.create_subscription(JointState, '/joint_states', lambda m: latest.update(q=np.array(m.position)), 10)
    procs = [start('sim_arm', 'real_time_factor:=2.0'),
             start('arm_command_bridge', f'trajectory_csv:={tmp_path / "g.csv"}', 'wait_for_arm:=30.0')]
    try:
        assert wait_for(lambda: statuses, timeout_s=40)
        assert statuses[-1].status[0].level == DiagnosticStatus.OK, statuses[-1].status[0].message
        assert wait_for(lambda: 'q' in latest and np.linalg.norm(
            planner.arm.gripper_positions(latest['q'])[0] - goal) < 2e-3, timeout_s=30)
    finally:
        for p in procs:
            p.send_signal(signal.SIGINT)
        codes = [p.wait(timeout=20) for p in procs]
    assert codes == [0, 0], [p.stderr.read() for p in procs]
