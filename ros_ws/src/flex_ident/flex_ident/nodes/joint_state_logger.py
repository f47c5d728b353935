"""joint_state_logger: record /joint_states (and /wrench, or any ``topics``) to a rosbag2, losslessly.

Parameters
  output  (string)    bag directory to create (default: joint_log_<UTC time> in the working directory)
  storage (string)    'mcap' (default) or 'sqlite3'
  topics  (string[])  topics to record (default: /joint_states, /wrench)
  close_after_idle_s (double) close the bag once no message arrived for this long after the first one
                      (default 0: record until stopped)

Services ``~/close`` (std_srvs/Trigger): close the bag now. When the bag is closed (idle, service, Ctrl-C/SIGTERM)
the node announces it on ``~/recorded`` (std_msgs/String JSON {"bag": path, "storage", "messages": {topic: n}},
RELIABLE + TRANSIENT_LOCAL): stiffness_identifier with ``recorded_topic:=/joint_state_logger/recorded`` identifies
it, which makes record -> identify one graph.

Like rosbag2, each topic is subscribed once a publisher appears, with the publisher's reliability
(RELIABLE if every publisher offers it, else BEST_EFFORT). Messages are recorded as received (serialized
bytes, stamped with the receive time), through a queue drained by a writer thread; the bag is flushed at
least every 0.5 s and closed cleanly on SIGINT/SIGTERM. Malformed JointState messages (non-finite values,
array lengths that disagree with ``name``) are recorded unchanged and counted in a throttled warning.
"""
from __future__ import annotations

import queue
import threading
import time
from collections import Counter

import json

import numpy as np
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from std_srvs.srv import Trigger

from robot_bridge.bagio.contract import JOINT_STATE_TYPE
from robot_bridge.bagio.raw import STORAGES, RawBagWriter, deserialize
from robot_bridge.nodes.common import declare_parameter, message_class, non_negative, run_node

DEFAULT_TOPICS = ['/joint_states', '/wrench']
SUBSCRIPTION_DEPTH = 10000
LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


def joint_state_problems(msg) -> list[str]:
    """Why a JointState is malformed (empty list if it is fine)."""
    problems = []
    n = len(msg.name)
    for field in ('position', 'velocity', 'effort'):
        values = np.asarray(getattr(msg, field), dtype=float)
        if len(values) not in (0, n):
            problems.append(f'{field} has {len(values)} values for {n} names')
        elif not np.all(np.isfinite(values)):
            problems.append(f'{field} is not finite')
    return problems


class JointStateLogger(Node):
    def __init__(self, **kwargs):
        super().__init__('joint_state_logger', **kwargs)
        default_out = time.strftime('joint_log_%Y%m%d_%H%M%S', time.gmtime())
        self.output = declare_parameter(self, 'output', default_out, 'bag directory to create')
        self.storage = declare_parameter(self, 'storage', 'mcap', "'mcap' or 'sqlite3'")
        self.topics = declare_parameter(
            self, 'topics', DEFAULT_TOPICS, 'topics to record', kind=list,
            check=lambda v: None if v else f'must name at least one topic (default: {DEFAULT_TOPICS})')
        self.close_after_idle_s = declare_parameter(
            self, 'close_after_idle_s', 0.0, 'close the bag after this many seconds without messages (0: never)',
            check=non_negative)
        if not self.output:
            raise ValueError("parameter 'output' must name the bag directory to create")
        if self.storage not in STORAGES:
            raise ValueError(f"parameter storage='{self.storage}' must be one of {sorted(STORAGES)}")
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._topic_subscriptions = {}
        self.counts: Counter = Counter()
        self.malformed = 0
        self._closed = False
        self.closed = threading.Event()
        self._close_lock = threading.Lock()
        self._last_message_s = None
        self._opened = threading.Event()
        self._open_error = None
        # The writer thread owns the bag for its whole life (sqlite3 connections are thread-bound).
        self._writer_thread = threading.Thread(target=self._write_loop, daemon=True)
        self._writer_thread.start()
        self._opened.wait()
        if self._open_error is not None:
            self._closed = True
            raise self._open_error
        self._discovery_timer = self.create_timer(0.05, self._subscribe_new_publishers)
        self.recorded_pub = self.create_publisher(String, '~/recorded', LATCHED)
        self.close_service = self.create_service(Trigger, '~/close', self._on_close_request)
        if self.close_after_idle_s > 0:
            self._idle_timer = self.create_timer(0.1, self._close_when_idle)
        self.get_logger().info(f'recording {self.topics} to {self.output} ({self.storage})')

    # -- subscriptions, as publishers appear ------------------------------------------------------------
    def _subscribe_new_publishers(self):
        for topic in self.topics:
            if topic in self._topic_subscriptions:
                continue
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            msgtype = infos[0].topic_type
            reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
            qos = QoSProfile(
                history=HistoryPolicy.KEEP_ALL, depth=SUBSCRIPTION_DEPTH,
                reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                durability=DurabilityPolicy.VOLATILE)
            try:
                cls = message_class(msgtype)
            except ValueError as exc:
                self.get_logger().error(f'cannot record {topic}: {exc}')
                self._topic_subscriptions[topic] = None
                continue
            self._topic_subscriptions[topic] = self.create_subscription(
                cls, topic, lambda data, t=topic, m=msgtype: self._on_message(t, m, data), qos, raw=True)
            self.get_logger().info(
                f"subscribed {topic} [{msgtype}] {'reliable' if reliable else 'best effort'}")

    def subscribed_topics(self) -> list[str]:
        return [t for t, s in self._topic_subscriptions.items() if s is not None]

    def _on_message(self, topic, msgtype, data):
        self._last_message_s = time.monotonic()
        self._queue.put((topic, msgtype, self.get_clock().now().nanoseconds, data))

    # -- writing ------------------------------------------------------------------------------------------
    def _write_loop(self):
        try:
            writer = RawBagWriter(self.output, storage=self.storage)
        except ValueError as exc:
            self._open_error = exc
            return
        finally:
            self._opened.set()
        try:
            while True:
                try:
                    item = self._queue.get(timeout=0.2)
                except queue.Empty:
                    writer.flush()
                    continue
                if item is None:
                    break
                self._write(writer, *item)
        finally:
            writer.close()

    def _write(self, writer, topic, msgtype, stamp_ns, data):
        writer.write(topic, msgtype, stamp_ns, data)
        self.counts[topic] += 1
        if msgtype == JOINT_STATE_TYPE:
            try:
                problems = joint_state_problems(deserialize(data, msgtype))
            except Exception as exc:  # undecodable bytes are still recorded
                problems = [f'undecodable ({exc})']
            if problems:
                self.malformed += 1
                self.get_logger().warn(
                    f'{self.malformed} malformed {topic} message(s) recorded as received; latest: '
                    + '; '.join(problems), throttle_duration_sec=2.0)

    def _close_when_idle(self):
        if self._last_message_s is not None and time.monotonic() - self._last_message_s > self.close_after_idle_s:
            self._idle_timer.cancel()
            self.get_logger().info(f'no message for {self.close_after_idle_s:g} s: closing the bag')
            self.close()

    def _on_close_request(self, _request, response):
        response.success = not self._closed
        self.close()
        response.message = f'closed {self.output}' if response.success else f'{self.output} was already closed'
        return response

    def close(self):
        """Write every queued message, close the bag and announce it on ~/recorded (idempotent)."""
        with self._close_lock:
            if self._closed:
                return
            self._closed = True
        self._discovery_timer.cancel()
        for sub in self._topic_subscriptions.values():   # nothing arrives after the sentinel
            if sub is not None:
                self.destroy_subscription(sub)
        self._topic_subscriptions = {t: None for t in self._topic_subscriptions}
        self._queue.put(None)
        self._writer_thread.join()
        summary = ', '.join(f'{t}: {n}' for t, n in sorted(self.counts.items())) or 'no messages'
        self.get_logger().info(f'closed {self.output}: {summary}; {self.malformed} malformed')
        if self.context.ok():
            try:
                self.recorded_pub.publish(String(data=json.dumps(
                    {'bag': str(self.output), 'storage': self.storage, 'messages': dict(self.counts)})))
            except Exception as exc:   # noqa: BLE001 - shutting down: the bag is closed, the announcement is moot
                self.get_logger().debug(f'could not announce the bag: {exc}')
        self.closed.set()


def main(args=None):
    return run_node(JointStateLogger, args=args)


if __name__ == '__main__':
    raise SystemExit(main())
