"""arm_command_bridge: gripper trajectory (table frame) -> joint trajectory for the arm, or a rejection on ~/status.

Subscribes  /gripper_trajectory (nav_msgs/Path, poses with stamps, in the table frame, CONTRACTS.md section 4)
            /joint_states (sensor_msgs/JointState): the arm's current joints seed the IK and the lead-in
Publishes   /arm_controller/joint_trajectory (trajectory_msgs/JointTrajectory, RELIABLE)
            ~/status (diagnostic_msgs/DiagnosticArray, RELIABLE + TRANSIENT_LOCAL): OK with the IK tracking error
            and the timing, or ERROR naming the first bad pose (index, time, xyz) and why

Parameters
  urdf (string, default: the project's Baxter right arm), base_link, tip_link, joints (string[])
  table_xyz, table_rpy (double[3]): the table frame in base_link [m, rad]
  grasp_xyz, grasp_rpy (double[3]): the gripper frame in tip_link [m, rad] (default identity: +z along the approach)
  velocity_scaling, acceleration_scaling (double in (0, 1]); acceleration_limits (double[], rad/s^2)
  position_tolerance (m, default 1e-4), orientation_tolerance (rad, default 1e-3)
  lead_in_s (double): time to reach the first pose when the arm's state is unknown (default 2 s); with a
            /joint_states reading it is computed from the limits
  trajectory_csv (string): also plan this CSV once, as soon as a command subscriber and /joint_states are there
            (or after wait_for_arm seconds, default 5)

A path is validated, solved and timed completely before anything is published; a rejected path publishes nothing.
Stamps: path time is header-relative (pose stamp - first pose stamp); all-zero stamps are an error (not increasing).
"""
from __future__ import annotations

import threading

import numpy as np
from builtin_interfaces.msg import Duration as DurationMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Path
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from robot_bridge.kinematics.gripper_path import GripperPath, PathRejected, read_gripper_csv
from robot_bridge.kinematics.planner import ArmCommandPlanner, BridgeConfig, JointPlan
from robot_bridge.nodes.common import run_node

COMMAND_TOPIC = '/arm_controller/joint_trajectory'
PATH_TOPIC = '/gripper_trajectory'
RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def path_from_msg(msg: Path) -> GripperPath:
    n = len(msg.poses)
    t = np.array([p.header.stamp.sec + 1e-9 * p.header.stamp.nanosec for p in msg.poses])
    xyz = np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in msg.poses]).reshape(n, 3)
    quat = np.array([[p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z, p.pose.orientation.w]
                     for p in msg.poses]).reshape(n, 4)
    return GripperPath(t - (t[0] if n else 0.0), xyz, quat)


def _duration(seconds: float) -> DurationMsg:
    ns = int(round(seconds * 1e9))
    return DurationMsg(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def trajectory_msg(plan: JointPlan, lead_in_s: float) -> JointTrajectory:
    """The plan as a JointTrajectory starting now (header stamp 0), its first point lead_in_s after the start."""
    msg = JointTrajectory()
    msg.joint_names = list(plan.joint_names)
    tr = plan.trajectory
    for k in range(len(tr.t_s)):
        msg.points.append(JointTrajectoryPoint(
            positions=tr.q[k].tolist(), velocities=tr.qd[k].tolist(), accelerations=tr.qdd[k].tolist(),
            time_from_start=_duration(lead_in_s + tr.t_s[k])))
    return msg


def declare_bridge_config(node: Node) -> BridgeConfig:
    """The arm and scene parameters (urdf, base_link, tip_link, joints, table_xyz/rpy, grasp_xyz/rpy, scalings,
    limits, tolerances) declared on ``node`` and read into a BridgeConfig; shared by every node that needs the
    bridge's kinematics (the deployment monitor computes the executed gripper path with them)."""
    d = BridgeConfig()

    def param(name, default, description):
        return node.declare_parameter(name, default, ParameterDescriptor(
            description=description, dynamic_typing=True)).value

    config = BridgeConfig(
        urdf=param('urdf', '', 'arm URDF (empty: the project\'s Baxter right arm)'),
        base_link=param('base_link', d.base_link, 'base frame of the arm'),
        tip_link=param('tip_link', d.tip_link, 'link holding the gripper frame'),
        joints=list(param('joints', d.joints, 'arm joints, base to tip')),
        table_xyz=tuple(param('table_xyz', list(d.table_xyz), 'table frame origin in base_link [m]')),
        table_rpy=tuple(param('table_rpy', list(d.table_rpy), 'table frame rpy in base_link [rad]')),
        grasp_xyz=tuple(param('grasp_xyz', list(d.grasp_xyz), 'gripper frame origin in tip_link [m]')),
        grasp_rpy=tuple(param('grasp_rpy', list(d.grasp_rpy), 'gripper frame rpy in tip_link [rad]')),
        velocity_scaling=param('velocity_scaling', 1.0, 'fraction of the joint velocity limits'),
        acceleration_scaling=param('acceleration_scaling', 1.0, 'fraction of the acceleration limits'),
        acceleration_limits_rad_s2=list(param('acceleration_limits', [0.0], 'rad/s^2 per joint ([0]: '
                                              'velocity limit / 0.5 s)')),
        position_tolerance_m=param('position_tolerance', d.position_tolerance_m, 'IK position tolerance [m]'),
        orientation_tolerance_rad=param('orientation_tolerance', d.orientation_tolerance_rad,
                                        'IK orientation tolerance [rad]'))
    if config.acceleration_limits_rad_s2 == [0.0]:
        config.acceleration_limits_rad_s2 = []
    return config


class ArmCommandBridge(Node):
    def __init__(self, **kwargs):
        super().__init__('arm_command_bridge', **kwargs)
        config = declare_bridge_config(self)

        def param(name, default, description):
            return self.declare_parameter(name, default, ParameterDescriptor(
                description=description, dynamic_typing=True)).value

        self.default_lead_in_s = float(param('lead_in_s', 2.0, 'time to the first pose if the arm state is unknown'))
        csv_path = param('trajectory_csv', '', 'gripper trajectory CSV to plan once at start')
        self.wait_for_arm_s = float(param('wait_for_arm', 5.0, 'with trajectory_csv: seconds to wait for a '
                                          'command subscriber and /joint_states before planning'))
        self.planner = ArmCommandPlanner(config)          # raises ValueError on a bad URDF/config
        self._lock = threading.Lock()
        self._joint_index = {n: i for i, n in enumerate(self.planner.arm.joint_names)}
        self.current_q: np.ndarray | None = None
        self.published = 0
        self.cmd_pub = self.create_publisher(JointTrajectory, COMMAND_TOPIC, RELIABLE)
        self.status_pub = self.create_publisher(DiagnosticArray, '~/status', LATCHED)
        self.create_subscription(JointState, '/joint_states', self._on_joint_states, qos_profile_sensor_data)
        self.create_subscription(Path, PATH_TOPIC, self._on_path, RELIABLE)
        self._csv = None
        if csv_path:
            try:
                self._csv = (read_gripper_csv(csv_path), csv_path)
            except ValueError as exc:
                self._status(DiagnosticStatus.ERROR, f'cannot read {csv_path}: {exc}', {})
                raise
            self._csv_deadline = self.get_clock().now().nanoseconds * 1e-9 + self.wait_for_arm_s
            self._csv_timer = self.create_timer(0.05, self._plan_csv_when_ready)

    def _plan_csv_when_ready(self):
        """The CSV is planned once a command subscriber and the arm's joint states are there (or after
        wait_for_arm seconds), so that the IK starts from the measured pose and the command is not lost."""
        ready = self.cmd_pub.get_subscription_count() > 0 and self.current_q is not None
        if not ready and self.get_clock().now().nanoseconds * 1e-9 < self._csv_deadline:
            return
        self._csv_timer.cancel()
        path, source = self._csv
        self.plan_and_publish(path, source=source)

    def _on_joint_states(self, msg: JointState):
        if len(msg.position) != len(msg.name):
            return
        q = np.full(len(self._joint_index), np.nan)
        for name, value in zip(msg.name, msg.position):
            i = self._joint_index.get(name)
            if i is not None:
                q[i] = value
        if np.all(np.isfinite(q)):
            with self._lock:
                self.current_q = q

    def _on_path(self, msg: Path):
        self.plan_and_publish(path_from_msg(msg), source=PATH_TOPIC)

    def plan_and_publish(self, path: GripperPath, source: str) -> bool:
        """Plan and publish; on rejection publish only the ERROR status. Returns whether a command went out."""
        with self._lock:
            q_now = None if self.current_q is None else self.current_q.copy()
        try:
            plan = self.planner.plan(path, q_start=q_now)
        except PathRejected as exc:
            self.get_logger().error(f'rejected {source}: {exc}')
            values = {'reason': exc.reason}
            if exc.index is not None:
                values.update({'index': exc.index, 't_s': exc.t_s, 'xyz_m': exc.xyz})
            self._status(DiagnosticStatus.ERROR, f'rejected: {exc}', values)
            return False
        lead_in = (self.default_lead_in_s if q_now is None
                   else self.planner.lead_in_time(q_now, plan.trajectory.q[0]))
        self.cmd_pub.publish(trajectory_msg(plan, lead_in))
        self.published += 1
        summary = plan.summary()
        summary['lead_in_s'] = lead_in
        self._status(DiagnosticStatus.OK,
                     f'{summary["poses"]} poses, {summary["duration_s"]:.2f} s; IK position error max '
                     f'{summary["position_max_m"] * 1e3:.4f} mm; {summary["timing"]}', summary)
        self.get_logger().info(f'published {source}: {summary["poses"]} poses, lead-in {lead_in:.2f} s, '
                               f'{summary["timing"]}')
        return True

    def _status(self, level, message: str, values: dict):
        status = DiagnosticStatus(level=level, name=self.get_fully_qualified_name(), message=message,
                                  hardware_id=self.planner.arm.robot.name)
        for key, value in values.items():
            if isinstance(value, dict):
                status.values.extend(KeyValue(key=f'{key}.{k}', value=str(v)) for k, v in value.items())
            else:
                status.values.append(KeyValue(key=key, value=str(value)))
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self.status_pub.publish(array)


def main(args=None) -> int:
    return run_node(lambda: ArmCommandBridge(), args=args)


if __name__ == '__main__':
    raise SystemExit(main())
