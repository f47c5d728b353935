"""pattern_perception in process: Image on /deploy_request -> nav_msgs/Path on /pattern (latched)."""
import numpy as np
import pytest
from nav_msgs.msg import Path
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image

from rod_deploy.nodes.pattern_perception import PatternPerception, image_to_bgr
from rod_deploy.perception.evaluation import centreline_rms
from rod_deploy.perception.synthetic import draw_strokes, example_curves

CURVE = example_curves(300)['letter_u']


def image_msg(bgr, encoding):
    if encoding == 'rgb8':
        data, c = bgr[:, :, ::-1], 3
    elif encoding == 'bgra8':
        data, c = np.dstack([bgr, np.full(bgr.shape[:2], 255, np.uint8)]), 4
    else:
        data, c = bgr.mean(axis=2).astype(np.uint8)[:, :, None], 1
    h, w = bgr.shape[:2]
    step = w * c + 8                                   # padded rows, as some drivers send
    buf = np.zeros((h, step), np.uint8)
    buf[:, :w * c] = data.reshape(h, w * c)
    msg = Image(height=h, width=w, encoding=encoding, step=step, data=buf.tobytes())
    msg.header.stamp.sec = 42
    return msg


@pytest.mark.parametrize('encoding', ['rgb8', 'bgra8', 'mono8'])
def test_image_conversion(encoding):
    bgr = np.random.default_rng(1).integers(0, 255, (5, 7, 3), dtype=np.uint8)
    out = image_to_bgr(image_msg(bgr, encoding))
    expect = bgr.mean(axis=2).astype(np.uint8) if encoding == 'mono8' else bgr
    assert np.array_equal(out, expect)
    with pytest.raises(ValueError, match='encoding'):
        image_to_bgr(Image(height=1, width=1, encoding='yuv422', step=2, data=b'\0\0'))


def test_request_image_becomes_a_latched_path(ros_context, wait_for):
    node = ros_context.add(PatternPerception(context=ros_context.context, parameter_overrides=[
        Parameter('m_per_px', value=0.001), Parameter('origin_row', value=299.0), Parameter('origin_col', value=0.0),
        Parameter('step_px', value=2.0)]))
    client = ros_context.add(rclpy_node(ros_context.context))
    received = []
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    pub = client.create_publisher(Image, '/deploy_request', QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
    assert wait_for(lambda: pub.get_subscription_count() > 0)

    # bad requests first: logged, no crash, nothing published
    pub.publish(Image(height=2, width=2, encoding='yuv422', step=4, data=bytes(8)))
    pub.publish(image_msg(np.full((50, 60, 3), 200, np.uint8), 'rgb8'))      # nothing to find
    assert wait_for(lambda: node.errors >= 1)

    img = draw_strokes((300, 300), [CURVE], [5.0], [(40, 30, 30)], noise_std=2)
    pub.publish(image_msg(img, 'rgb8'))
    assert wait_for(lambda: node.published == 1, timeout_s=20)
    # a subscriber that comes late still gets the pattern (TRANSIENT_LOCAL)
    client.create_subscription(Path, '/pattern', received.append, latched)
    assert wait_for(lambda: received, timeout_s=10)
    path = received[0]
    assert path.header.frame_id == 'table' and path.header.stamp.sec == 42
    xy = np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses])
    rows, cols = 299.0 - xy[:, 1] / 0.001, xy[:, 0] / 0.001
    assert centreline_rms(np.stack([rows, cols], axis=1), CURVE)['rms_px'] < 1.0
    q = path.poses[len(path.poses) // 2].pose.orientation
    assert abs(q.x) < 1e-12 and abs(q.y) < 1e-12 and abs(q.z ** 2 + q.w ** 2 - 1) < 1e-9


def rclpy_node(context):
    from rclpy.node import Node
    return Node('pattern_perception_test_client', context=context)


def test_homography_parameter(ros_context):
    with pytest.raises(ValueError, match='9 numbers'):
        PatternPerception(context=ros_context.context,
                          parameter_overrides=[Parameter('homography', value=[1.0, 0.0, 0.0])])
    node = ros_context.add(PatternPerception(context=ros_context.context, parameter_overrides=[
        Parameter('homography', value=[0.001, 0.0, 0.0, 0.0, -0.001, 0.3, 0.0, 0.0, 1.0])]))
    x, y = node._mapping((300, 400)).to_table(np.array([300.0]), np.array([100.0]))
    assert np.allclose([x[0], y[0]], [0.1, 0.0])
