"""deployment_monitor: follows a deployment request through the graph and lays the rod along what the arm did.

The graph: /deploy_request -> pattern_perception -> /pattern -> grasp_trajectory_generator -> /gripper_trajectory
-> arm_command_bridge -> /arm_controller/joint_trajectory -> the arm (sim_arm or a real one) -> /joint_states.
This node watches it: a request starts when pattern_perception reports 'request received' on its ~/status (or when
a /pattern arrives with no request open); it keeps the prescribed pattern, the planned gripper trajectory, the
joint command and the measured joint states until they cover the command; then, in a worker thread, the executed
gripper path (forward kinematics of the measured joints, ``robot_bridge.kinematics.execution``) drives the rod
simulation (``rod_deploy.deployment.executed``) and the result is published and saved in ``out/request_<n>/``.

A request that fails anywhere gets a result naming the stage and why: ``perception`` / ``planning`` /
``arm_command`` (an ERROR on that node's ~/status, e.g. an IK rejection naming the first bad pose), ``execution``
(no joint states, the arm not following the command), ``rod_simulation``, ``timeout`` (nothing for ``timeout_s``
before the rod simulation starts), ``superseded`` (a new request arrived first).

Publishes  /deploy_result (std_msgs/String JSON, RELIABLE + TRANSIENT_LOCAL): {"request", "e_mean_cm", "sigma_cm",
           "e_max_cm", "coverage", ..., "timings_s", "tracking", "files"} or {"request", "error", "stage",
           "timings_s"}
           /deployed_shape (nav_msgs/Path, table frame, latched): the deployed rod on the table
           /deploy_markers (visualization_msgs/MarkerArray, latched): pattern, planned and executed gripper paths,
           IK arm poses of the command, deployed rod
Parameters the rod (rod_yaml, or length, radius, L_gb), the arm and scene as in arm_command_bridge (urdf, table_xyz,
           ...: give both nodes the same), out (default 'deployments'), edge_length_m (0.005), dt_s (0.02),
           max_gripper_speed_m_s (0.01), friction (< 0: the rod file's), timeout_s (300),
           joint_state_timeout_s (5), arm_pose_markers (number of IK arm poses drawn, 6)
"""
from __future__ import annotations

import json
import threading
import time
from collections import deque
from pathlib import Path as FsPath

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from robot_bridge.kinematics.execution import (ExecutionError, executed_gripper_path, joint_matrix,
                                               path_deviation_m)
from robot_bridge.kinematics.gripper_path import GripperPath
from robot_bridge.kinematics.planner import ArmCommandPlanner
from robot_bridge.nodes.arm_command_bridge import declare_bridge_config
from robot_bridge.nodes.common import LatestMessageWorker, declare_parameter, positive, run_node
from robot_bridge.nodes.markers import line_strip, marker_array
from rod_deploy.deployment.executed import deploy_along_executed_path
from rod_deploy.deployment.simulate import SimulationSettings, lead_in_rows
from rod_deploy.nodes.grasp_trajectory_generator import declare_rod, trajectory_from_path

LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
RELIABLE = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE)
JOINT_STATES_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)
STAGE_OF_NODE = {'/pattern_perception/status': 'perception', '/grasp_trajectory_generator/status': 'planning',
                 '/arm_command_bridge/status': 'arm_command'}
REACHED_RAD = 2e-3          # the arm is at the command's last point when every joint is this close ...
SETTLED_S = 0.3             # ... and the joint states go on this long after that (stamp time)
MAX_JOINT_RMS_RAD = 0.05    # measured vs commanded joints beyond this: the arm did not follow the command


def _stamp_s(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


class DeploymentMonitor(Node):
    def __init__(self, **kwargs):
        super().__init__('deployment_monitor', **kwargs)
        self.rod = declare_rod(self)
        self.bridge_config = declare_bridge_config(self)
        self.out = FsPath(declare_parameter(self, 'out', 'deployments', 'directory for the saved results'))
        friction = declare_parameter(self, 'friction', -1.0, "Coulomb coefficient (< 0: the rod file's)")
        self.settings = SimulationSettings(
            edge_length_m=declare_parameter(self, 'edge_length_m', 0.005, 'rod edge length [m]', check=positive),
            dt_s=declare_parameter(self, 'dt_s', 0.02, 'implicit Euler step [s]', check=positive),
            max_gripper_speed_m_s=declare_parameter(self, 'max_gripper_speed_m_s', 0.01,
                                                    'replay speed of the gripper path [m/s]', check=positive),
            friction=None if friction < 0 else friction)
        self.timeout_s = declare_parameter(self, 'timeout_s', 300.0, 'seconds from the request to the rod '
                                           'simulation before the request fails', check=positive)
        self.joint_state_timeout_s = declare_parameter(self, 'joint_state_timeout_s', 5.0,
                                                       'seconds without /joint_states during execution',
                                                       check=positive)
        self.arm_pose_markers = declare_parameter(self, 'arm_pose_markers', 6, 'IK arm poses drawn',
                                                  check=lambda v: None if v >= 0 else 'must be >= 0')
        self.planner = ArmCommandPlanner(self.bridge_config)      # forward kinematics (worker thread only)
        self._marker_planner = ArmCommandPlanner(self.bridge_config)   # arm pose markers (executor threads)
        self._lock = threading.Lock()
        self._request: dict | None = None
        self._count = 0
        self._recent = deque(maxlen=400)            # (stamp, names, positions) before a command arrives
        self._markers = {}
        self.results: list[dict] = []
        self.result_pub = self.create_publisher(String, '/deploy_result', LATCHED)
        self.shape_pub = self.create_publisher(Path, '/deployed_shape', LATCHED)
        self.marker_pub = self.create_publisher(MarkerArray, '/deploy_markers', LATCHED)
        for topic in STAGE_OF_NODE:
            self.create_subscription(DiagnosticArray, topic, lambda m, t=topic: self._on_status(t, m), RELIABLE)
        self.create_subscription(Path, '/pattern', self._on_pattern, RELIABLE)
        self.create_subscription(Path, '/gripper_trajectory', self._on_gripper_trajectory, RELIABLE)
        self.create_subscription(JointTrajectory, '/arm_controller/joint_trajectory', self._on_command, RELIABLE)
        self.create_subscription(JointState, '/joint_states', self._on_joint_states, JOINT_STATES_QOS)
        self._worker = LatestMessageWorker(self._deploy, 'deployment')
        self.create_timer(0.5, self._check_timeouts)
        self.get_logger().info(f'following deployment requests (rod {self.rod.length_m:g} m); results on '
                               f'/deploy_result, files in {self.out}/')

    # -- the request's stages --------------------------------------------------------------------------------------
    def _new_request(self, source: str):
        """Open a request (the caller holds the lock); an open one is superseded."""
        if self._request is not None and self._request['stage'] != 'rod_simulation':
            self._fail_locked('superseded', 'a new deployment request arrived before this one finished')
        self._count += 1
        now = time.monotonic()
        self._request = {'id': self._count, 'source': source, 'stage': 'perception', 't': {'request': now},
                         'last_joint_state': now}
        self._markers = {}

    def _on_status(self, topic: str, msg: DiagnosticArray):
        if not msg.status:
            return
        st = msg.status[0]
        with self._lock:
            if topic == '/pattern_perception/status' and st.message == 'request received':
                self._new_request('perception')
                return
            if self._request is None or self._request['stage'] == 'rod_simulation':
                return
            values = {kv.key: kv.value for kv in st.values}
            if st.level == DiagnosticStatus.ERROR:
                self._fail_locked(STAGE_OF_NODE[topic], st.message, values)
            elif topic == '/arm_command_bridge/status':
                self._request['bridge'] = values

    def _on_pattern(self, msg: Path):
        xy = np.array([[p.pose.position.x, p.pose.position.y] for p in msg.poses], float).reshape(-1, 2)
        with self._lock:
            if self._request is None or self._request['stage'] not in ('perception', 'planning'):
                self._new_request('pattern')
            r = self._request
            r.update(pattern=xy, stage='planning')
            r['t']['pattern'] = time.monotonic()
            self._markers['pattern'] = line_strip('prescribed_pattern', 0, xy, 'black', 0.004, 'table')
            self._publish_markers_locked()

    def _on_gripper_trajectory(self, msg: Path):
        if not msg.poses:
            return
        planned = trajectory_from_path(msg)
        with self._lock:
            r = self._request
            if r is None or r['stage'] != 'planning':
                return
            r.update(planned=planned, stage='arm_command')
            r['t']['trajectory'] = time.monotonic()
            self._markers['planned'] = line_strip('planned_gripper_path', 0, planned[1], 'red', 0.003, 'table')
            self._publish_markers_locked()
            early = r.pop('early_command', None)
            if early is not None:                # the bridge's command was delivered before its gripper trajectory
                self._accept_command_locked(r, early)

    def _on_command(self, msg: JointTrajectory):
        if not msg.points:
            return
        with self._lock:
            r = self._request
            if r is not None and r['stage'] == 'planning':
                # the bridge plans from /gripper_trajectory too: on a loaded machine its command can be delivered
                # here before the trajectory it answers; kept until that trajectory arrives (the latest one)
                r['early_command'] = msg
                return
            if r is None or r['stage'] != 'arm_command':
                return
            self._accept_command_locked(r, msg)

    def _accept_command_locked(self, r: dict, msg: JointTrajectory):
        if len(msg.points) != len(r['planned'][0]):
            return
        tfs = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in msg.points])
        q_cmd = np.array([p.positions for p in msg.points])
        try:
            order = [list(msg.joint_names).index(j) for j in self.planner.arm.joint_names]
        except ValueError:
            self._fail_locked('arm_command', f'the command lacks some of the joints '
                              f'{self.planner.arm.joint_names}')
            return
        guess = self._recent[-1][0] if self._recent else None
        r.update(stage='execution', command=(tfs, q_cmd[:, order]), guess=guess,
                 samples=list(self._recent), last_joint_state=time.monotonic())
        r['t']['command'] = time.monotonic()
        self._markers.update(self._arm_pose_markers(q_cmd[:, order]))
        self._publish_markers_locked()

    def _on_joint_states(self, msg: JointState):
        sample = (_stamp_s(msg), list(msg.name), list(msg.position))
        with self._lock:
            r = self._request
            if r is None or r['stage'] != 'execution':
                self._recent.append(sample)
                return
            r['samples'].append(sample)
            r['last_joint_state'] = time.monotonic()
            if r['guess'] is None:
                r['guess'] = sample[0]
            if not self._executed_locked(r, msg):
                return
            r['stage'] = 'rod_simulation'
            r['t']['executed'] = time.monotonic()
            job = dict(r)
        self._worker.submit(job)

    def _executed_locked(self, r: dict, msg: JointState) -> bool:
        """Whether the joint states cover the command: the arm has been at the command's last point for
        SETTLED_S (or, if it never gets there, the command is long overdue: the fit then says how far off it is)."""
        tfs, q_cmd = r['command']
        stamp = r['samples'][-1][0]
        if stamp < r['guess'] + tfs[-1]:
            return False
        if r.get('reached') is None:
            try:
                q = joint_matrix([msg.name], [msg.position], self.planner.arm.joint_names)[0]
            except ExecutionError:
                return False
            if np.max(np.abs(q - q_cmd[-1])) < REACHED_RAD:
                r['reached'] = stamp
        if r.get('reached') is not None:
            return stamp >= r['reached'] + SETTLED_S
        return stamp >= r['guess'] + 2.0 * tfs[-1] + 10.0

    def _check_timeouts(self):
        now = time.monotonic()
        with self._lock:
            r = self._request
            if r is None or r['stage'] == 'rod_simulation':
                return
            if r['stage'] == 'execution' and now - r['last_joint_state'] > self.joint_state_timeout_s:
                self._fail_locked('execution', f'no /joint_states from the arm for {self.joint_state_timeout_s:g} s '
                                  f'while it should execute the command')
            elif now - r['t']['request'] > self.timeout_s:
                self._fail_locked('timeout', f'no progress past stage {r["stage"]} within {self.timeout_s:g} s')

    # -- the rod along the executed path (worker thread) --------------------------------------------------------------
    def _deploy(self, r: dict):
        try:
            summary, result = self._simulate(r)
        except (ExecutionError, ValueError) as exc:
            stage = 'execution' if isinstance(exc, ExecutionError) else 'rod_simulation'
            with self._lock:
                self._fail_locked(stage, str(exc), r=r)
            return
        except Exception as exc:       # noqa: BLE001 - every failure becomes a result, the node stays up
            with self._lock:
                self._fail_locked('rod_simulation', f'{type(exc).__name__}: {exc}', r=r)
            return
        shape = Path()
        shape.header.frame_id = 'table'
        shape.header.stamp = self.get_clock().now().to_msg()
        z = self.rod.radius_m
        for x, y in result.deployed_xy:
            pose = PoseStamped()
            pose.header = shape.header
            pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = float(x), float(y), z
            pose.pose.orientation.w = 1.0
            shape.poses.append(pose)
        with self._lock:
            self.shape_pub.publish(shape)
            self._markers['deployed'] = line_strip('deployed_rod', 0, np.column_stack(
                [result.deployed_xy, np.full(len(result.deployed_xy), z)]), 'blue', 0.004, 'table')
            self._markers['rod'] = line_strip('deployed_rod', 1, result.nodes, 'green', 0.002, 'table')
            self._publish_markers_locked()
            self._finish_locked(summary)

    def _simulate(self, r: dict):
        tfs, q_cmd = r['command']
        stamps = np.array([s[0] for s in r['samples']])
        keep = np.concatenate([[True], np.diff(stamps) > 0])      # drop repeated stamps (a re-sent message)
        samples = [s for s, k in zip(r['samples'], keep) if k]
        q_meas = joint_matrix([s[1] for s in samples], [s[2] for s in samples], self.planner.arm.joint_names)
        executed = executed_gripper_path(self.planner, stamps[keep], q_meas, tfs, q_cmd, r['guess'] - 0.2)
        if executed.joint_rms_rad > MAX_JOINT_RMS_RAD:
            raise ExecutionError(f'the arm did not follow the command: measured joints {executed.joint_rms_rad:.3f} '
                                 f'rad RMS from the commanded ones')
        t_plan, p_plan, q_plan = r['planned']
        planned = GripperPath(t_plan, p_plan, q_plan)
        deviation = path_deviation_m(executed.path, planned)
        with self._lock:
            self._markers['executed'] = line_strip('executed_gripper_path', 0, executed.path.xyz_m, 'orange', 0.002,
                                                   'table')
            self._publish_markers_locked()
        bridge = r.get('bridge', {})
        extra = {'request': r['id'], 'source': r['source'],
                 'tracking': {'executed_vs_planned_max_mm': 1e3 * deviation['max_m'],
                              'executed_vs_planned_rms_mm': 1e3 * deviation['rms_m'],
                              'ik_position_max_mm': 1e3 * float(bridge.get('position_max_m', 'nan')),
                              'command_start_correction_s': executed.start_correction_s,
                              'measured_vs_commanded_joints_rms_rad': executed.joint_rms_rad,
                              'joint_states_used': executed.samples_used}}
        t0 = time.monotonic()
        summary, result = deploy_along_executed_path(
            r['pattern'], t_plan, executed.path.xyz_m, executed.path.quat_xyzw, lead_in_rows(p_plan), self.rod,
            self.settings, self.out / f'request_{r["id"]:03d}', planned=(t_plan, p_plan, q_plan), extra=extra)
        r['t']['done'] = time.monotonic()
        summary['timings_s'] = self._timings(r)
        summary['timings_s']['rod_simulation'] = round(r['t']['done'] - t0, 3)
        FsPath(summary['files']['json']).write_text(json.dumps(summary, indent=2, default=float) + '\n')
        return summary, result

    # -- results --------------------------------------------------------------------------------------------------
    @staticmethod
    def _timings(r: dict) -> dict:
        """Seconds per stage of a request (a stage not reached is left out; 'total' up to now or the end)."""
        t = dict(r['t'])
        t.setdefault('done', time.monotonic())
        spans = {'perception': ('request', 'pattern'), 'planning': ('pattern', 'trajectory'),
                 'arm_command_and_execution': ('trajectory', 'executed'), 'total': ('request', 'done')}
        return {k: round(t[b] - t[a], 3) for k, (a, b) in spans.items() if a in t and b in t}

    def _fail_locked(self, stage: str, why: str, values: dict | None = None, r: dict | None = None):
        r = r or self._request
        result = {'request': r['id'] if r else None, 'error': why, 'stage': stage,
                  'timings_s': self._timings(r) if r else {}}
        if values:
            result['details'] = {k: v for k, v in values.items() if k != 'request'}
        self.get_logger().error(f'deployment request {result["request"]} failed at {stage}: {why}')
        self._publish_result_locked(result)

    def _finish_locked(self, summary: dict):
        self.get_logger().info(f'deployment request {summary["request"]}: e_mean {summary["e_mean_cm"]:.3f} cm, '
                               f'sigma {summary["sigma_cm"]:.3f} cm, {summary["timings_s"]["total"]:.1f} s; '
                               f'{summary["files"]["json"]}')
        self._publish_result_locked(summary)

    def _publish_result_locked(self, result: dict):
        if self._request is not None and self._request['id'] == result['request']:
            self._request = None          # (a request simulated in the worker may finish after a newer one opened)
        self.results.append(result)
        self.result_pub.publish(String(data=json.dumps(result, default=float)))

    # -- markers --------------------------------------------------------------------------------------------------
    def _arm_pose_markers(self, q) -> dict:
        n = min(int(self.arm_pose_markers), len(q))
        if n == 0:
            return {}
        to_table = np.linalg.inv(self._marker_planner.table)
        out = {}
        for i, k in enumerate(np.linspace(0, len(q) - 1, n).round().astype(int)):
            pts = self._marker_planner.arm.chain_points(q[k])
            pts = (to_table[:3, :3] @ pts.T).T + to_table[:3, 3]
            out[f'arm{i}'] = line_strip('ik_arm_poses', i, pts, 'purple', 0.01, 'table')
        return out

    def _publish_markers_locked(self):
        self.marker_pub.publish(marker_array(list(self._markers.values())))

    def close(self):
        self._worker.close(timeout_s=5.0)


def main(args=None):
    return run_node(DeploymentMonitor, args=args)


if __name__ == '__main__':
    raise SystemExit(main())
