"""End to end, in one process: bag_player replays a bag, joint_state_logger records it, bags are equal."""
import numpy as np
import pytest
from rclpy.parameter import Parameter

from flex_ident.nodes.joint_state_logger import JointStateLogger
from robot_bridge.bagio.contract import JointRecording, write_joint_recording
from robot_bridge.bagio.raw import RawBagWriter, iter_raw_messages, serialize, TYPESTORE
from robot_bridge.nodes.bag_player import BagPlayer


def make_bag(path, storage, n=300, extra_topic=True, nan_at=None):
    rng = np.random.default_rng(1)
    names = ['j1', 'j2', 'j3', 'gripper_finger']
    pos = rng.normal(size=(n, 4))
    if nan_at is not None:
        pos[nan_at, 1] = np.nan
    rec = JointRecording(np.arange(n) * 0.002, names, pos, rng.normal(size=(n, 4)), rng.normal(size=(n, 4)),
                         stamp0_ns=1_700_000_000_000_000_000)
    write_joint_recording(path, rec, storage=storage, receive_lag_s=0.003)
    if extra_topic:   # add an unrelated topic by rewriting into a second bag
        merged = str(path) + '_merged'
        String = TYPESTORE.types['std_msgs/msg/String']
        with RawBagWriter(merged, storage=storage) as w:
            for i, m in enumerate(iter_raw_messages(path)):
                w.write(m.topic, m.msgtype, m.timestamp_ns, m.data)
                if i % 50 == 0:
                    w.write('/unrelated', 'std_msgs/msg/String', m.timestamp_ns + 1,
                            serialize(String(data=f'note {i}'), 'std_msgs/msg/String'))
        return merged
    return str(path)


def record_replay(ros_context, wait_for, bag, out, storage, topics, rate=1.0):
    logger = ros_context.add(JointStateLogger(context=ros_context.context, parameter_overrides=[
        Parameter('output', value=str(out)), Parameter('storage', value=storage),
        Parameter('topics', value=topics)]))
    player = ros_context.add(BagPlayer(context=ros_context.context, parameter_overrides=[
        Parameter('bag', value=str(bag)), Parameter('rate', value=rate),
        Parameter('wait_for_subscribers', value=10.0)]))
    assert wait_for(lambda: player.done.is_set(), timeout_s=60)
    assert player.exit_code == 0
    expected = {t: n for t, n in count_topics(bag).items() if t in topics}
    assert wait_for(lambda: dict(logger.counts) == expected, timeout_s=10), (dict(logger.counts), expected)
    logger.close()
    return logger


def count_topics(bag):
    counts = {}
    for m in iter_raw_messages(bag):
        counts[m.topic] = counts.get(m.topic, 0) + 1
    return counts


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_replayed_bag_is_recorded_message_by_message(ros_context, wait_for, tmp_path, storage):
    bag = make_bag(tmp_path / 'in', storage)
    topics = ['/joint_states', '/unrelated']
    record_replay(ros_context, wait_for, bag, tmp_path / 'out', storage, topics, rate=4.0)
    original = [m for m in iter_raw_messages(bag)]
    recorded = [m for m in iter_raw_messages(tmp_path / 'out')]
    for topic in topics:
        a = [m.data for m in original if m.topic == topic]
        b = [m.data for m in recorded if m.topic == topic]
        assert len(a) == len(b) > 0
        assert a == b   # same order, stamps (in the header) and values, byte for byte


def test_malformed_messages_are_recorded_and_counted(ros_context, wait_for, tmp_path):
    bag = make_bag(tmp_path / 'in', 'mcap', n=100, extra_topic=False, nan_at=[10, 20, 30])
    logger = record_replay(ros_context, wait_for, bag, tmp_path / 'out', 'mcap', ['/joint_states'], rate=5.0)
    assert logger.malformed == 3
    assert [m.data for m in iter_raw_messages(tmp_path / 'out')] == [m.data for m in iter_raw_messages(bag)]


def test_logger_matches_a_best_effort_publisher(ros_context, wait_for, tmp_path):
    """A RELIABLE subscription would not match a BEST_EFFORT publisher: the logger must adapt."""
    from rclpy.qos import ReliabilityPolicy
    bag = make_bag(tmp_path / 'in', 'mcap', n=100, extra_topic=False)
    logger = ros_context.add(JointStateLogger(context=ros_context.context, parameter_overrides=[
        Parameter('output', value=str(tmp_path / 'out')), Parameter('topics', value=['/joint_states'])]))
    player = ros_context.add(BagPlayer(context=ros_context.context, parameter_overrides=[
        Parameter('bag', value=str(bag)), Parameter('reliable', value=False), Parameter('rate', value=2.0),
        Parameter('wait_for_subscribers', value=10.0)]))
    assert wait_for(lambda: player.done.is_set(), timeout_s=30)
    sub = logger._topic_subscriptions['/joint_states']
    assert sub.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
    assert wait_for(lambda: logger.counts['/joint_states'] == 100, timeout_s=5), logger.counts


def test_player_topics_and_remap(ros_context, wait_for, tmp_path):
    bag = make_bag(tmp_path / 'in', 'mcap', n=120)
    logger = ros_context.add(JointStateLogger(context=ros_context.context, parameter_overrides=[
        Parameter('output', value=str(tmp_path / 'out')), Parameter('topics', value=['/robot/js', '/unrelated'])]))
    player = ros_context.add(BagPlayer(context=ros_context.context, parameter_overrides=[
        Parameter('bag', value=bag), Parameter('rate', value=4.0), Parameter('wait_for_subscribers', value=10.0),
        Parameter('topics', value=['/joint_states']), Parameter('remap', value=['/joint_states:=/robot/js'])]))
    assert wait_for(lambda: player.done.is_set(), timeout_s=30) and player.exit_code == 0
    assert wait_for(lambda: logger.counts['/robot/js'] == 120, timeout_s=5), logger.counts
    logger.close()
    recorded = list(iter_raw_messages(tmp_path / 'out'))
    assert {m.topic for m in recorded} == {'/robot/js'}             # /unrelated was not replayed
    assert [m.data for m in recorded] == [m.data for m in iter_raw_messages(bag, topics=['/joint_states'])]


def test_player_start_offset_skips_the_beginning(ros_context, wait_for, tmp_path):
    bag = make_bag(tmp_path / 'in', 'mcap', n=300, extra_topic=False)      # 0.6 s at 500 Hz
    original = list(iter_raw_messages(bag))
    expected = [m.data for m in original if m.timestamp_ns >= original[0].timestamp_ns + 300_000_000]
    assert 100 < len(expected) < 200
    logger = ros_context.add(JointStateLogger(context=ros_context.context, parameter_overrides=[
        Parameter('output', value=str(tmp_path / 'out')), Parameter('topics', value=['/joint_states'])]))
    player = ros_context.add(BagPlayer(context=ros_context.context, parameter_overrides=[
        Parameter('bag', value=bag), Parameter('start_offset', value=0.3), Parameter('wait_for_subscribers', value=10.0)]))
    assert wait_for(lambda: player.done.is_set(), timeout_s=30) and player.exit_code == 0
    assert wait_for(lambda: logger.counts['/joint_states'] == len(expected), timeout_s=5), logger.counts
    logger.close()
    assert [m.data for m in iter_raw_messages(tmp_path / 'out')] == expected


def test_player_loop_replays_again_until_stopped(ros_context, wait_for, tmp_path):
    bag = make_bag(tmp_path / 'in', 'mcap', n=50, extra_topic=False)
    logger = ros_context.add(JointStateLogger(context=ros_context.context, parameter_overrides=[
        Parameter('output', value=str(tmp_path / 'out')), Parameter('topics', value=['/joint_states'])]))
    player = ros_context.add(BagPlayer(context=ros_context.context, parameter_overrides=[
        Parameter('bag', value=bag), Parameter('loop', value=True), Parameter('rate', value=5.0),
        Parameter('wait_for_subscribers', value=10.0)]))
    assert wait_for(lambda: logger.counts['/joint_states'] >= 120, timeout_s=30), logger.counts
    assert not player.done.is_set()
    player.close()
    assert player.done.is_set()
    logger.close()
    once = [m.data for m in iter_raw_messages(bag)]
    recorded = [m.data for m in iter_raw_messages(tmp_path / 'out')]
    assert recorded[:100] == once + once                              # the same bag, twice, in order


def test_wrench_and_mixed_reliability_publishers_are_recorded(ros_context, wait_for, tmp_path):
    """/wrench is recorded by default; two /joint_states publishers, one RELIABLE and one BEST_EFFORT: the logger
    subscribes BEST_EFFORT (as rosbag2 does) so that it hears both."""
    import rclpy
    from geometry_msgs.msg import WrenchStamped
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    logger = ros_context.add(JointStateLogger(context=ros_context.context, parameter_overrides=[
        Parameter('output', value=str(tmp_path / 'out'))]))
    node = ros_context.add(rclpy.create_node('publishers', context=ros_context.context))
    reliable = node.create_publisher(JointState, '/joint_states',
                                     QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    best_effort = node.create_publisher(JointState, '/joint_states',
                                        QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT))
    wrench = node.create_publisher(WrenchStamped, '/wrench', QoSProfile(depth=100))
    assert wait_for(lambda: set(logger.subscribed_topics()) == {'/joint_states', '/wrench'}, timeout_s=10)
    sub = logger._topic_subscriptions['/joint_states']
    assert sub.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
    assert wait_for(lambda: reliable.get_subscription_count() and best_effort.get_subscription_count()
                    and wrench.get_subscription_count(), timeout_s=10)
    import time
    for i in range(20):
        reliable.publish(JointState(name=['a'], position=[float(i)]))
        best_effort.publish(JointState(name=['b'], position=[float(i)]))
        w = WrenchStamped()
        w.wrench.force.z = float(i)
        wrench.publish(w)
        time.sleep(0.005)
    assert wait_for(lambda: logger.counts['/joint_states'] == 40 and logger.counts['/wrench'] == 20, timeout_s=5), \
        logger.counts
    logger.close()
    from robot_bridge.bagio.raw import deserialize
    names = [deserialize(m.data, m.msgtype).name[0] for m in iter_raw_messages(tmp_path / 'out', ['/joint_states'])]
    assert names.count('a') == 20 and names.count('b') == 20
    forces = [deserialize(m.data, m.msgtype).wrench.force.z for m in iter_raw_messages(tmp_path / 'out', ['/wrench'])]
    assert forces == [float(i) for i in range(20)]
