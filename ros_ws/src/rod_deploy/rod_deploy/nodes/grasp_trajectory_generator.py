"""grasp_trajectory_generator: a pattern (``nav_msgs/Path`` on ``/pattern``) in, the gripper trajectory that lays the
rod along it out (``nav_msgs/Path`` of stamped poses on ``/gripper_trajectory``), planned by paper Alg. 4.

Subscribes ``/pattern`` (RELIABLE + TRANSIENT_LOCAL depth 1, as ``pattern_perception`` publishes it; points in the
table frame [m], z ignored) and plans in a worker thread (a pattern arriving while one is planned replaces any queued
one). Publishes ``/gripper_trajectory`` (RELIABLE + TRANSIENT_LOCAL depth 1, frame ``table``): the poses of
``rod-deploy plan`` (position = the held node of the rod, orientation = the gripper frame, +z_gripper along which
the rod leaves it; CONTRACTS.md section 4), each stamped with the start time plus its time along the trajectory.
Status on ``~/status`` (``diagnostic_msgs/DiagnosticArray``): OK with the summary, or ERROR naming the problem (too
long for the rod, too sharp, fewer than 3 points, NaN, repeated points, a bad rod) - never a partial trajectory.

Parameters
  rod_yaml     (string)  rod description YAML (CONTRACTS.md section 4); or the three below
  length, radius, L_gb (double)  rod length, radius h, gravito-bending length [m] (used when rod_yaml is empty)
  method       (string)  nn (default), numeric or intuitive
  step_m       (double)  node spacing along the pattern (default 0.005)
  smoothing_m  (double)  RMS distance of the smoothing spline from the pattern points (default 0.0005)
  speed_m_s    (double)  gripper speed (default 0.01)
  start        (string)  achievable (default: the start bent only as far as the table friction holds it, the rod
                         file's friction or 0.5) or tangent (Alg. 4's start)
"""
from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.time import Time

from robot_bridge.nodes.common import LatestMessageWorker, declare_parameter, non_negative, positive, run_node
from rod_deploy.planning.rod_description import RodDescription, load_rod_description, rod_description_from_dict
from rod_deploy.planning.trajectory import METHODS, STARTS, PlannerSettings, plan_trajectory, warm_up

LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


def declare_rod(node: Node) -> RodDescription:
    """The rod from parameter 'rod_yaml', or 'length', 'radius' and 'L_gb' [m] (shared with deployment_monitor)."""
    rod_yaml = declare_parameter(node, 'rod_yaml', '', 'rod description YAML (else length, radius, L_gb)')
    length = declare_parameter(node, 'length', 0.0, 'rod length [m]', check=non_negative)
    radius = declare_parameter(node, 'radius', 0.0, 'rod radius h [m]', check=non_negative)
    lgb = declare_parameter(node, 'L_gb', 0.0, 'gravito-bending length [m]', check=non_negative)
    if rod_yaml:
        return load_rod_description(rod_yaml)
    if length and radius and lgb:
        return rod_description_from_dict({'length': length, 'radius': radius, 'L_gb': lgb}, 'parameters')
    raise ValueError("give the rod: parameter 'rod_yaml', or 'length', 'radius' and 'L_gb' [m]")


class GraspTrajectoryGenerator(Node):
    def __init__(self, **kwargs):
        super().__init__('grasp_trajectory_generator', **kwargs)
        self.rod = declare_rod(self)
        method = declare_parameter(self, 'method', 'nn', 'nn, numeric or intuitive',
                                   check=lambda v: None if v in METHODS else f'must be one of {METHODS}')
        step = declare_parameter(self, 'step_m', 0.005, 'node spacing along the pattern [m]', check=positive)
        smoothing = declare_parameter(self, 'smoothing_m', 0.0005, 'smoothing spline RMS distance [m]',
                                      check=non_negative)
        speed = declare_parameter(self, 'speed_m_s', 0.01, 'gripper speed [m/s]', check=positive)
        start = declare_parameter(self, 'start', PlannerSettings.start, 'achievable (friction-limited) or tangent',
                                  check=lambda v: None if v in STARTS else f'must be one of {STARTS}')
        self.settings = PlannerSettings(method=method, step_m=step, smoothing_m=smoothing, speed_m_s=speed,
                                        start=start)
        self.settings.validate()
        startup_s = warm_up(self.rod, self.settings)         # the first request is then planned in milliseconds
        self.publisher = self.create_publisher(Path, '/gripper_trajectory', LATCHED)
        self.status = self.create_publisher(DiagnosticArray, '~/status', LATCHED)
        self.published = 0
        self.errors = 0
        self._worker = LatestMessageWorker(self._process, 'planner')
        self.subscription = self.create_subscription(Path, '/pattern', self._worker.submit, LATCHED)
        self.get_logger().info(f'waiting for patterns on /pattern (rod {self.rod.length_m:g} m, L_gb '
                               f'{self.rod.gravito_bending_length_m:g} m, method {method}; planner loaded in '
                               f'{startup_s:.2f} s)')

    def _process(self, msg: Path):
        points = np.array([[p.pose.position.x, p.pose.position.y] for p in msg.poses], float).reshape(-1, 2)
        try:
            plan = plan_trajectory(points, self.rod, self.settings)
        except Exception as exc:    # noqa: BLE001 - every failure is reported on the status topic, none published
            self.errors += 1
            text = str(exc) if isinstance(exc, ValueError) else f'{type(exc).__name__}: {exc}'
            self.get_logger().error(f'pattern rejected: {text}')
            self._publish_status(DiagnosticStatus.ERROR, f'pattern rejected: {text}', {'points': len(points)})
            return
        start = self.get_clock().now()
        out = Path()
        out.header.stamp = start.to_msg()
        out.header.frame_id = 'table'
        for ti, p, q in zip(plan.t, plan.position, plan.quaternion):
            pose = PoseStamped()
            pose.header.frame_id = 'table'
            pose.header.stamp = (start + Duration(nanoseconds=int(round(ti * 1e9)))).to_msg()
            pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = (float(v) for v in p)
            (pose.pose.orientation.x, pose.pose.orientation.y, pose.pose.orientation.z,
             pose.pose.orientation.w) = (float(v) for v in q)
            out.poses.append(pose)
        self.publisher.publish(out)
        self.published += 1
        summary = {'poses': len(plan.t), 'pattern_nodes': len(plan.pattern.s),
                   'pattern_length_m': round(plan.pattern.length, 4), 'duration_s': round(float(plan.t[-1]), 2),
                   'method': plan.method, 'planning_time_s': round(plan.timings_s['total'], 4),
                   'planned_curve_max_deviation_m': round(plan.asked_deviation()[0], 4)}
        self._publish_status(DiagnosticStatus.OK, 'trajectory published', summary)
        self.get_logger().info(f'published /gripper_trajectory: {summary}')

    def _publish_status(self, level, message, values):
        st = DiagnosticStatus(level=level, name=self.get_fully_qualified_name(), message=message,
                              values=[KeyValue(key=str(k), value=str(v)) for k, v in values.items()])
        arr = DiagnosticArray(status=[st])
        arr.header.stamp = self.get_clock().now().to_msg()
        self.status.publish(arr)

    def close(self):
        self._worker.close()


def trajectory_from_path(msg: Path):
    """(t [s] from the first pose, position (n, 3), quaternion (n, 4)) of a stamped gripper Path."""
    t0 = Time.from_msg(msg.poses[0].header.stamp).nanoseconds
    t = np.array([(Time.from_msg(p.header.stamp).nanoseconds - t0) * 1e-9 for p in msg.poses])
    pos = np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in msg.poses])
    quat = np.array([[p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z, p.pose.orientation.w]
                     for p in msg.poses])
    return t, pos, quat


def main(args=None):
    return run_node(GraspTrajectoryGenerator, args=args)


if __name__ == '__main__':
    raise SystemExit(main())
