"""pattern_perception: the deployment request in, the pattern as ``nav_msgs/Path`` out.

Subscribes ``/deploy_request``: a ``sensor_msgs/Image`` of a drawn pattern (rgb8, bgr8, mono8, rgba8, bgra8,
mono16/16UC1; RELIABLE, depth 1, or the sensor-data QoS with ``best_effort_input``), or with
``request_type:=path`` a ``nav_msgs/Path`` of pattern points already in the table frame [m] (one process cannot
hold two message types on one topic name, hence the parameter). Perceives the strokes or rods in a worker thread
(the subscription never waits for processing; a request arriving while one is processed replaces any queued one)
and publishes ``/pattern`` (``nav_msgs/Path``, frame ``table``, RELIABLE + TRANSIENT_LOCAL, depth 1): the
centreline of object ``object_index`` (default 0, the longest) in table metres, z = 0, each pose's yaw along the
path (a Path request is checked - at least 3 finite points - and passed on). Several objects: the chosen one is
published and the others are logged. ``~/status`` (``diagnostic_msgs/DiagnosticArray``, RELIABLE +
TRANSIENT_LOCAL): OK 'request received' (key ``request`` counts them) when a request arrives, then OK with the
summary or ERROR saying why (unknown encoding, wrong size, nothing found, a bad path).

Parameters
  m_per_px            (double)   table metres per pixel s (default 0.001)
  origin_row          (double)   origin pixel row r0; < 0: the bottom row (default -1)
  origin_col          (double)   origin pixel column c0 (default 0)
  homography          (double[]) 9 numbers, row-major H of (x, y, 1) ~ H (col, row, 1); overrides the scale
  step_px             (double)   point spacing along the path [px] (default 2)
  object_index        (int)      object to publish (default 0)
  best_effort_input   (bool)     subscribe with the sensor-data QoS (default false: RELIABLE)
  request_type        (string)   'image' (default) or 'path'
"""
from __future__ import annotations

import math

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from rclpy.node import Node
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy,
                       qos_profile_sensor_data)
from sensor_msgs.msg import Image

from robot_bridge.nodes.common import (FLOAT_LIST, LatestMessageWorker, declare_parameter, non_negative, positive,
                                       run_node)
from rod_deploy.perception.pipeline import PerceptionConfig, PerceptionError, perceive
from rod_deploy.perception.pixel_mapping import Homography, MappingError, ScaleOrigin

REQUEST_TYPES = {'image': Image, 'path': Path}
CHANNELS = {'rgb8': 3, 'bgr8': 3, 'mono8': 1, '8UC1': 1, '8UC3': 3, 'rgba8': 4, 'bgra8': 4,
            'mono16': 1, '16UC1': 1}


def image_to_bgr(msg: Image) -> np.ndarray:
    """uint8 BGR (or grey) array of a ``sensor_msgs/Image``; ValueError for what cannot be converted."""
    enc = msg.encoding
    if enc not in CHANNELS:
        raise ValueError(f"unsupported image encoding '{enc}' (supported: {', '.join(CHANNELS)})")
    c = CHANNELS[enc]
    depth = 2 if enc in ('mono16', '16UC1') else 1
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    if h == 0 or w == 0:
        raise ValueError(f'empty image ({w} x {h})')
    if step < w * c * depth or len(msg.data) < h * step:
        raise ValueError(f'image data too short: {len(msg.data)} bytes for {w} x {h} {enc} with step {step}')
    buf = np.frombuffer(bytes(msg.data), np.uint8)[:h * step].reshape(h, step)[:, :w * c * depth]
    if depth == 2:
        dtype = '>u2' if msg.is_bigendian else '<u2'
        grey = buf.copy().view(dtype).reshape(h, w).astype(np.float32)
        return np.clip(grey / 257.0, 0, 255).astype(np.uint8)
    img = buf.reshape(h, w, c)
    if enc == 'rgb8':
        return img[:, :, ::-1].copy()
    if enc == 'rgba8':
        return img[:, :, 2::-1].copy()
    if enc == 'bgra8':
        return img[:, :, :3].copy()
    if c == 1:
        return img[:, :, 0].copy()
    return img.copy()


def yaw_quaternion(yaw: float):
    return 0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)


class PatternPerception(Node):
    def __init__(self, **kwargs):
        super().__init__('pattern_perception', **kwargs)
        self.m_per_px = declare_parameter(self, 'm_per_px', 0.001, 'table metres per pixel', check=positive)
        self.origin_row = declare_parameter(self, 'origin_row', -1.0, 'origin pixel row r0 (< 0: bottom row)')
        self.origin_col = declare_parameter(self, 'origin_col', 0.0, 'origin pixel column c0')
        homography = declare_parameter(
            self, 'homography', [], 'row-major 3x3 H, (x, y, 1) ~ H (col, row, 1); empty: use m_per_px',
            kind=FLOAT_LIST)
        step = declare_parameter(self, 'step_px', 2.0, 'point spacing along the path [px]',
                                 check=lambda v: None if 0.1 <= v <= 100.0 else 'must be between 0.1 and 100')
        self.object_index = declare_parameter(self, 'object_index', 0, 'object to publish (0: the longest)',
                                              check=non_negative)
        best_effort = declare_parameter(self, 'best_effort_input', False,
                                        'subscribe with the sensor-data QoS (default: RELIABLE)')
        self.request_type = declare_parameter(
            self, 'request_type', 'image', "message type on /deploy_request: 'image' or 'path'",
            check=lambda v: None if v in REQUEST_TYPES else f'must be one of {sorted(REQUEST_TYPES)}')
        self.homography = None
        if homography:
            if len(homography) != 9:
                raise ValueError(f'parameter homography needs 9 numbers (row-major 3x3), got {len(homography)}')
            try:
                self.homography = Homography(np.array(homography, float).reshape(3, 3))
            except MappingError as exc:
                raise ValueError(f'parameter homography: {exc}') from None
        self.config = PerceptionConfig(step_px=step)

        latched = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        request_qos = qos_profile_sensor_data if best_effort else QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE)
        self.publisher = self.create_publisher(Path, '/pattern', latched)
        self.status = self.create_publisher(DiagnosticArray, '~/status', latched)
        self.published = 0
        self.errors = 0
        self.requests = 0
        self._worker = LatestMessageWorker(self._handle, 'perception')
        self.subscription = self.create_subscription(REQUEST_TYPES[self.request_type], '/deploy_request',
                                                     self._on_request, request_qos)
        self.get_logger().info(f'waiting for {self.request_type} requests on /deploy_request; the pattern goes to '
                               f'/pattern')

    def _on_request(self, msg):
        self.requests += 1
        self._publish_status(DiagnosticStatus.OK, 'request received', {'request': self.requests})
        self._worker.submit(msg)

    def _handle(self, msg):
        what = 'image' if isinstance(msg, Image) else 'path'
        try:
            summary = self._process(msg) if isinstance(msg, Image) else self._pass_path(msg)
        except (ValueError, MappingError) as exc:     # PerceptionError is a ValueError
            self.errors += 1
            self.get_logger().error(f'deployment request {what} rejected: {exc}')
            self._publish_status(DiagnosticStatus.ERROR, f'request {what} rejected: {exc}', {'request': self.requests})
            return
        except Exception as exc:                       # keep the node alive whatever the request
            self.errors += 1
            text = f'perception failed on the request {what}: {type(exc).__name__}: {exc}'
            self.get_logger().error(text)
            self._publish_status(DiagnosticStatus.ERROR, text, {'request': self.requests})
            return
        self._publish_status(DiagnosticStatus.OK, 'pattern published', dict(summary, request=self.requests))

    def _publish_status(self, level, message: str, values: dict):
        st = DiagnosticStatus(level=level, name=self.get_fully_qualified_name(), message=message,
                              values=[KeyValue(key=str(k), value=str(v)) for k, v in values.items()])
        arr = DiagnosticArray(status=[st])
        arr.header.stamp = self.get_clock().now().to_msg()
        self.status.publish(arr)

    def _pass_path(self, msg: Path) -> dict:
        """A pattern given as points in the table frame: checked and passed on to /pattern."""
        xy = np.array([[p.pose.position.x, p.pose.position.y] for p in msg.poses], float).reshape(-1, 2)
        if len(xy) < 3:
            raise ValueError(f'a pattern needs at least 3 points, got {len(xy)}')
        bad = np.flatnonzero(~np.all(np.isfinite(xy), axis=1))
        if bad.size:
            raise ValueError(f'point {int(bad[0])} of the pattern is not finite')
        if msg.header.frame_id not in ('', 'table'):
            raise ValueError(f"the pattern must be in the 'table' frame, got '{msg.header.frame_id}'")
        self.publisher.publish(self._path_message(msg, xy[:, 0], xy[:, 1]))
        self.published += 1
        length = float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))
        self.get_logger().info(f'published /pattern: {len(xy)} points of the request path, {length:.3f} m')
        return {'points': len(xy), 'length_m': round(length, 4)}

    def _mapping(self, shape):
        if self.homography is not None:
            self.homography.check_image(shape)
            return self.homography
        r0 = self.origin_row if self.origin_row >= 0 else shape[0] - 1.0
        return ScaleOrigin(self.m_per_px, r0, self.origin_col)

    def _process(self, msg: Image):
        image = image_to_bgr(msg)
        mapping = self._mapping(image.shape)
        try:
            result = perceive(image, self.config)
        except PerceptionError as exc:
            raise ValueError(str(exc)) from None
        n = len(result.objects)
        if self.object_index >= n:
            raise ValueError(f'object_index {self.object_index} but the image has {n} object(s)')
        obj = result.objects[self.object_index]
        x, y = mapping.to_table(obj.points[:, 0], obj.points[:, 1])
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
            raise ValueError('the mapping sends path points to infinity')
        self.publisher.publish(self._path_message(msg, x, y))
        self.published += 1
        length = float(np.sum(np.hypot(np.diff(x), np.diff(y))))
        note = f'; {n - 1} other object(s) not published' if n > 1 else ''
        self.get_logger().info(f'published /pattern: object {self.object_index} of {n}, {len(x)} points, '
                               f'{length:.3f} m, {result.timings_ms["total"]:.0f} ms{note}')
        return {'objects': n, 'points': len(x), 'length_m': round(length, 4),
                'perception_ms': round(float(result.timings_ms['total']), 1)}

    def _path_message(self, msg, x: np.ndarray, y: np.ndarray) -> Path:
        path = Path()
        stamp = msg.header.stamp
        if stamp.sec == 0 and stamp.nanosec == 0:
            stamp = self.get_clock().now().to_msg()
        path.header.stamp = stamp
        path.header.frame_id = 'table'
        dx = np.gradient(x) if len(x) > 1 else np.zeros(1)
        dy = np.gradient(y) if len(y) > 1 else np.zeros(1)
        for xi, yi, dxi, dyi in zip(x.tolist(), y.tolist(), dx.tolist(), dy.tolist()):
            pose = PoseStamped()
            pose.header = path.header
            pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = xi, yi, 0.0
            q = yaw_quaternion(math.atan2(dyi, dxi))
            pose.pose.orientation.x, pose.pose.orientation.y, pose.pose.orientation.z, pose.pose.orientation.w = q
            path.poses.append(pose)
        return path

    def close(self):
        self._worker.close()


def main(args=None):
    return run_node(PatternPerception, args=args)


if __name__ == '__main__':
    raise SystemExit(main())
