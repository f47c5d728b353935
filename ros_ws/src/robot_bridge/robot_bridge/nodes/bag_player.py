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

import threading
import time

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, ParameterType
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from robot_bridge.bagio.raw import BagError, iter_raw_messages, topic_types
from robot_bridge.nodes.common import message_class, run_node

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
        positive = ParameterDescriptor(floating_point_range=[FloatingPointRange(
            from_value=1e-3, to_value=1e3, step=0.0)], description='speed factor')
        self.bag = self.declare_parameter('bag', '', ParameterDescriptor(description='bag directory')).value
        self.rate = self.declare_parameter('rate', 1.0, positive).value
        self.start_offset = self.declare_parameter('start_offset', 0.0).value
        self.loop = self.declare_parameter('loop', False).value
        topics = list(self.declare_parameter('topics', [], ParameterDescriptor(
            type=ParameterType.PARAMETER_STRING_ARRAY, description='topics to replay (default: all)')).value)
        remap = list(self.declare_parameter('remap', [], ParameterDescriptor(
            type=ParameterType.PARAMETER_STRING_ARRAY, description="'/from:=/to' renames")).value)
        self.wait_for_subscribers = self.declare_parameter('wait_for_subscribers', 5.0).value
        reliable = self.declare_parameter('reliable', True).value
        if not self.bag:
            raise ValueError("parameter 'bag' is required (the bag directory to replay)")
        if self.start_offset < 0:
            raise ValueError(f'start_offset must be >= 0 s, got {self.start_offset}')
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
            self._topic_publishers[msg.topic].publish(msg.data)
            self.published += 1

    def close(self):
        self._stop.set()
        self._thread.join(timeout=10)


def main(args=None):
    return run_node(BagPlayer, args=args, until=lambda node: node.done.is_set())


if __name__ == '__main__':
    raise SystemExit(main())
