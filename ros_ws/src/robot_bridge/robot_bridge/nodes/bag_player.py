"""bag_player: fake hardware that replays a rosbag2 with its original timing, then exits.

Parameters
  bag                   (string)   bag directory (required)
  rate                  (double)   speed factor (default 1.0; 2.0 plays twice as fast)
  start_offset          (double)   seconds of the bag to skip (default 0)
  loop                  (bool)     replay forever (default false)
  topics                (string[]) topics to replay (default: all)
  remap                 (string[]) 'from:=to' topic renames, e.g. ['/joint_states:=/robot/joint_states']
  wait_for_subscribers  (double)   seconds to wait for a first subscriber before playing (default 5); then up to
                                   1 s more while subscribers of the other topics appear
  reliable              (bool)     publish RELIABLE (default) or BEST_EFFORT

Messages are published as the serialized bytes stored in the bag (nothing is re-encoded), at
t_wall = t_start + (t_bag - t_first) / rate. With reliable delivery the player waits for every
subscriber to acknowledge before it exits. A missing, empty or corrupt bag gives one error line and
exit status 1.
"""
from __future__ import annotations

import sys
import threading
import time

from rclpy._rclpy_pybind11 import RCLError
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from robot_bridge.bagio.raw import BagError, iter_raw_messages, topic_types
from robot_bridge.nodes.common import declare_parameter, message_class, non_negative, run_node

PUBLISHER_DEPTH = 10000


def parse_remaps(remaps: list[str]) -> dict[str, str]:
    out = {}
    for item in remaps:
        sep = ':=' if ':=' in item else ':'
        src, _, dst = item.partition(sep)
        if not src.startswith('/') or not dst.startswith('/'):
            raise ValueError(f"remap '{item}' is not of the form '/from:=/to'")
        out[src] = dst
    return out


SETTLE_S = 1.0        # after the first subscriber, wait this long for subscribers of the other topics
MATCH_GRACE_S = 0.1   # then this long for the subscribers' side of the match


class BagPlayer(Node):
    def __init__(self, **kwargs):
        super().__init__('bag_player', **kwargs)
        self.bag = declare_parameter(self, 'bag', '', 'bag directory (required)')
        self.rate = declare_parameter(self, 'rate', 1.0, 'speed factor (2.0 plays twice as fast)',
                                      check=lambda v: None if 1e-3 <= v <= 1e3 else 'must be between 0.001 and 1000')
        self.start_offset = declare_parameter(self, 'start_offset', 0.0, 'seconds of the bag to skip',
                                              check=non_negative)
        self.loop = declare_parameter(self, 'loop', False, 'replay forever')
        topics = declare_parameter(self, 'topics', [], 'topics to replay (default: all)', kind=list)
        remap = declare_parameter(self, 'remap', [], "'/from:=/to' topic renames", kind=list)
        self.wait_for_subscribers = declare_parameter(
            self, 'wait_for_subscribers', 5.0, 'seconds to wait for a first subscriber', check=non_negative)
        reliable = declare_parameter(self, 'reliable', True, 'publish RELIABLE (true) or BEST_EFFORT')
        if not self.bag:
            raise ValueError("parameter 'bag' is required (the bag directory to replay)")
        types = topic_types(self.bag)
        wanted = [t for t in topics if t]
        unknown = [t for t in wanted if t not in types]
        if unknown:
            raise BagError(f'topic(s) {unknown} not in bag {self.bag} (it has {sorted(types)})')
        self.topics = wanted or sorted(types)
        remaps = parse_remaps([r for r in remap if r])
        self._first_ns = self._first_timestamp()
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=PUBLISHER_DEPTH,
                         reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.VOLATILE)
        self._topic_publishers = {t: self.create_publisher(message_class(types[t]), remaps.get(t, t), qos)
                            for t in self.topics}
        self.published = 0
        self.exit_code = 0
        self.done = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._play, daemon=True)
        self._thread.start()

    def _first_timestamp(self) -> int:
        for msg in iter_raw_messages(self.bag, topics=self.topics):
            return msg.timestamp_ns
        raise BagError(f'bag {self.bag} has no messages on {self.topics}')

    def _wait_for_subscribers(self):
        """Wait for a first subscriber; then let the others join (a recorder subscribes topic by topic as it
        discovers them): play once every topic has one, or once no new topic matched for SETTLE_S."""
        deadline = time.monotonic() + self.wait_for_subscribers
        matched, last_change = set(), None
        while time.monotonic() < deadline and not self._stop.is_set():
            now_matched = {t for t, p in self._topic_publishers.items() if p.get_subscription_count() > 0}
            if now_matched - matched:
                matched |= now_matched
                last_change = time.monotonic()
            if matched and (len(matched) == len(self._topic_publishers) or time.monotonic() - last_change > SETTLE_S):
                time.sleep(MATCH_GRACE_S)   # the subscriber side matches the writer a moment after we see it
                return True
            time.sleep(0.01)
        return bool(matched)

    def _play(self):
        try:
            if self.wait_for_subscribers > 0 and not self._wait_for_subscribers():
                self.get_logger().warn(f'no subscriber after {self.wait_for_subscribers} s; playing anyway')
            while True:
                self._play_once()
                if not self.loop or self._stop.is_set():
                    break
            if not self.context.ok() or self._stop.is_set():
                # interrupted (Ctrl-C / SIGTERM): the ROS logger's context may be gone already
                print(f'bag_player: stopped after {self.published} messages from {self.bag}', file=sys.stderr)
                return
            for pub in self._topic_publishers.values():
                pub.wait_for_all_acked(Duration(seconds=5))
            self.get_logger().info(f'played {self.published} messages from {self.bag}')
        except BagError as exc:
            self.get_logger().error(str(exc))
            self.exit_code = 1
        finally:
            self.done.set()

    def _play_once(self):
        start_ns = self._first_ns + int(self.start_offset * 1e9)
        t_wall0 = None
        for msg in iter_raw_messages(self.bag, topics=self.topics, start_ns=start_ns):
            if self._stop.is_set():
                return
            if t_wall0 is None:
                t_wall0, t_bag0 = time.monotonic(), msg.timestamp_ns
            delay = t_wall0 + (msg.timestamp_ns - t_bag0) * 1e-9 / self.rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            try:
                self._topic_publishers[msg.topic].publish(msg.data)
            except RCLError:
                if self._stop.is_set() or not self.context.ok():
                    return          # Ctrl-C / SIGTERM shut the context down under us: stop quietly
                raise
            self.published += 1

    def close(self):
        self._stop.set()
        self._thread.join(timeout=10)


def main(args=None):
    return run_node(BagPlayer, args=args, until=lambda node: node.done.is_set())


if __name__ == '__main__':
    raise SystemExit(main())
