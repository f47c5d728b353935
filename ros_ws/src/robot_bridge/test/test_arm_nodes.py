"""arm_command_bridge and sim_arm in one process: rejections publish nothing; a path is executed by the simulated
arm and the forward kinematics of the measured joints follow it."""
import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from robot_bridge.kinematics.example_paths import deployment_like_path
from robot_bridge.kinematics.gripper_path import write_gripper_csv
from robot_bridge.nodes.arm_command_bridge import ArmCommandBridge
from robot_bridge.nodes.sim_arm import SimArm

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def path_msg(path, node):
    msg = Path()
    msg.header.frame_id = 'table'
    for t, p, q in zip(path.t_s, path.xyz_m, path.quat_xyzw):
        ps = PoseStamped()
        ps.header.frame_id = 'table'
        ps.header.stamp.sec, ps.header.stamp.nanosec = int(t), int(round((t - int(t)) * 1e9))
        ps.pose.position.x, ps.pose.position.y, ps.pose.position.z = (float(v) for v in p)
        ps.pose.orientation.x, ps.pose.orientation.y, ps.pose.orientation.z, ps.pose.orientation.w = \
            (float(v) for v in q)
        msg.poses.append(ps)
    return msg


class Probe:
    """A node counting joint trajectories and keeping the bridge's status messages and the joint states."""

    def __init__(self, ros_context):
        from rclpy.node import Node
        self.node = ros_context.add(Node('probe', context=ros_context.context))
        self.commands, self.statuses, self.joint_states = [], [], []
        self.node.create_subscription(JointTrajectory, '/arm_controller/joint_trajectory', self.commands.append,
                                      RELIABLE)
        self.node.create_subscription(DiagnosticArray, '/arm_command_bridge/status', self.statuses.append, LATCHED)
        self.node.create_subscription(JointState, '/joint_states', self.joint_states.append, QoSProfile(
            depth=5000, reliability=ReliabilityPolicy.RELIABLE))
        self.path_pub = self.node.create_publisher(Path, '/gripper_trajectory', RELIABLE)


def short_path(n=15, duration_s=1.5):
    return deployment_like_path(n_poses=n, duration_s=duration_s, radius_m=0.05, height_m=(0.35, 0.45),
                                max_tilt_rad=0.3)


def test_bridge_rejects_bad_paths_before_publishing_any_command(ros_context, wait_for):
    bridge = ros_context.add(ArmCommandBridge(context=ros_context.context))
    probe = Probe(ros_context)
    assert wait_for(lambda: bridge.count_subscribers('/arm_controller/joint_trajectory') >= 1
                    and probe.path_pub.get_subscription_count() >= 1)
    bad = {}
    nan = short_path()
    nan.quat_xyzw[4, 2] = np.nan
    bad['NaN'] = nan
    far = short_path()
    far.xyz_m[6] += [0.0, 0.0, 2.0]
    bad['unreachable'] = far
    bad['empty'] = None                      # a Path message without poses
    for what, path in bad.items():
        before = len(probe.statuses)
        probe.path_pub.publish(Path() if path is None else path_msg(path, probe.node))
        assert wait_for(lambda: len(probe.statuses) > before), what
        status = probe.statuses[-1].status[0]
        assert status.level == DiagnosticStatus.ERROR, (what, status.message)
        assert len(probe.commands) == 0 and bridge.published == 0, what
        values = {kv.key: kv.value for kv in status.values}
        if what == 'NaN':
            assert values['index'] == '4' and 'NaN' in status.message
        elif what == 'unreachable':
            assert values['index'] == '6' and 'unreachable' in status.message
        else:
            assert 'empty' in status.message
    # a good path does go out, so the counter above could have seen one
    probe.path_pub.publish(path_msg(short_path(), probe.node))
    assert wait_for(lambda: len(probe.commands) == 1)
    # the OK status follows the command on another topic: on a loaded machine it may arrive a moment later
    assert wait_for(lambda: probe.statuses[-1].status[0].level == DiagnosticStatus.OK)
    assert len(probe.commands[0].points) == 15


def test_bridge_rejects_a_pose_beyond_a_joint_limit_from_a_csv_parameter(ros_context, wait_for, tmp_path):
    from robot_bridge.kinematics.arm import default_urdf_path
    urdf = tmp_path / 'narrow.urdf'
    urdf.write_text(default_urdf_path().read_text().replace('lower="-0.05" upper="2.618"', 'lower="-0.05" upper="0.9"'))
    write_gripper_csv(tmp_path / 'g.csv', short_path())
    probe = Probe(ros_context)
    bridge = ros_context.add(ArmCommandBridge(context=ros_context.context, parameter_overrides=[
        Parameter('urdf', value=str(urdf)), Parameter('trajectory_csv', value=str(tmp_path / 'g.csv')),
        Parameter('wait_for_arm', value=0.2)]))
    assert wait_for(lambda: len(probe.statuses) >= 1)      # the latched status of the CSV plan
    status = probe.statuses[-1].status[0]
    assert status.level == DiagnosticStatus.ERROR and 'right_e1' in status.message and 'beyond its limits' in \
        status.message
    assert bridge.published == 0 and len(probe.commands) == 0


def test_sim_arm_executes_the_bridges_trajectory_and_follows_the_path(ros_context, wait_for):
    sim = ros_context.add(SimArm(context=ros_context.context, parameter_overrides=[
        Parameter('real_time_factor', value=2.0), Parameter('rate_hz', value=200.0)]))
    bridge = ros_context.add(ArmCommandBridge(context=ros_context.context))
    probe = Probe(ros_context)
    assert wait_for(lambda: bridge.current_q is not None and probe.path_pub.get_subscription_count() >= 1
                    and bridge.cmd_pub.get_subscription_count() >= 2, timeout_s=20)      # the probe and sim_arm
    path = short_path(n=20, duration_s=2.0)
    probe.path_pub.publish(path_msg(path, probe.node))
    # generous timeouts: they cost nothing when the machine is quiet, and a loaded CI machine slows both the
    # simulation (which then runs slower than real time) and the delivery of /joint_states
    assert wait_for(lambda: len(probe.commands) == 1 and sim.trajectory_done, timeout_s=120), \
        (len(probe.commands), sim.commands_received, sim.sim_time_s, sim.error, probe.statuses[-1:])
    status = {kv.key: kv.value for kv in probe.statuses[-1].status[0].values}
    lead_in, scale = float(status['lead_in_s']), float(status['time_scale'])
    t0 = sim.trajectory_start_s + lead_in
    stamp0 = sim.stamp0.nanoseconds * 1e-9

    def last_stamp():
        m = probe.joint_states[-1]
        return m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec - stamp0

    # the sim is done when it has stepped past the trajectory; on a loaded machine the probe may still be receiving
    assert wait_for(lambda: last_stamp() >= t0 + path.t_s[-1] * scale, timeout_s=120), \
        (last_stamp(), t0, len(probe.joint_states), sim.sim_time_s, sim.slower_than_real_time)
    names = probe.joint_states[0].name
    samples = [(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec - stamp0, np.array(m.position))
               for m in list(probe.joint_states)]
    t_meas = np.array([s[0] for s in samples]) - t0
    inside = (t_meas >= 0) & (t_meas <= path.t_s[-1] * scale)
    assert names == list(bridge.planner.arm.joint_names) and inside.sum() > 100
    q_meas = np.array([s[1] for s in samples])[inside]
    fk = bridge.planner.arm.gripper_positions(q_meas)
    targets = bridge.planner.to_base(path)[:, :3, 3]
    expected = np.column_stack([np.interp(t_meas[inside] / scale, path.t_s, targets[:, j]) for j in range(3)])
    error = np.linalg.norm(fk - expected, axis=1)
    # the controller's share: measured gripper vs the gripper of the commanded trajectory at the same time
    cmd = probe.commands[0]
    t_cmd = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in cmd.points])
    spline = CubicHermiteSpline(t_cmd, [p.positions for p in cmd.points], [p.velocities for p in cmd.points])
    fk_cmd = bridge.planner.arm.gripper_positions(spline(t_meas[inside] + lead_in))
    lag = np.linalg.norm(fk - fk_cmd, axis=1)
    print(f'measured gripper vs path: max {error.max() * 1e3:.2f} mm, RMS {np.sqrt(np.mean(error ** 2)) * 1e3:.2f} '
          f'mm; vs the commanded trajectory: max {lag.max() * 1e3:.3f} mm, over {inside.sum()} samples '
          f'(time scale {scale:.2f}, lead-in {lead_in:.2f} s)')
    assert error.max() < 5e-3 and lag.max() < 1e-3
    # the efforts are the actuator torques: holding the arm against gravity takes tens of N m at the shoulder
    assert np.max(np.abs(probe.joint_states[-1].effort)) > 5.0


def test_sim_arm_holds_the_experiments_loop_at_1khz(ros_context, wait_for):
    from pathlib import Path
    experiment = Path(__file__).resolve().parents[4] / 'bags' / 'example_loop12' / 'experiment.yaml'
    if not experiment.exists():
        pytest.skip('example experiment not in this checkout')
    probe = Probe(ros_context)
    sim = ros_context.add(SimArm(context=ros_context.context, parameter_overrides=[
        Parameter('experiment', value=str(experiment)), Parameter('hold_object', value=True),
        Parameter('rate_hz', value=1000.0), Parameter('effort_bias', value=[0.25])]))
    # on a loaded machine the 12-link loop at 1 kHz runs slower than real time (the stamps stay 1 ms apart)
    assert wait_for(lambda: len(probe.joint_states) >= 300, timeout_s=20), \
        f'{len(probe.joint_states)} received of {sim.published} published, sim error: {sim.error}'
    stamps = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in list(probe.joint_states)[:300]])
    assert np.allclose(np.diff(stamps), 1e-3, atol=2e-6)
    assert sim.follower.sim.has_loop and sim.follower.sim.weld_residual()[0] < 1e-5
    assert list(probe.joint_states[0].name) == sim.names and len(probe.joint_states[0].effort) == 7
