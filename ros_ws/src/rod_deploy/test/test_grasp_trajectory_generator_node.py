"""grasp_trajectory_generator in process: nav_msgs/Path on /pattern -> stamped gripper Path on /gripper_trajectory;
bad patterns give an ERROR status and publish nothing."""
import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from rclpy.parameter import Parameter

from rod_deploy.nodes.grasp_trajectory_generator import LATCHED, GraspTrajectoryGenerator, trajectory_from_path
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory


def path_msg(xy):
    msg = Path()
    msg.header.frame_id = 'table'
    for x, y in xy:
        p = PoseStamped()
        p.pose.position.x, p.pose.position.y = float(x), float(y)
        msg.poses.append(p)
    return msg


def test_pattern_in_trajectory_out_and_errors(ros_context, wait_for):
    node = ros_context.add(GraspTrajectoryGenerator(context=ros_context.context, parameter_overrides=[
        Parameter('length', value=0.89), Parameter('radius', value=0.002), Parameter('L_gb', value=0.034)]))
    client = ros_context.add(rclpy.create_node('client', context=ros_context.context))
    trajectories, statuses = [], []
    client.create_subscription(Path, '/gripper_trajectory', trajectories.append, LATCHED)
    client.create_subscription(DiagnosticArray, '/grasp_trajectory_generator/status', statuses.append, LATCHED)
    pub = client.create_publisher(Path, '/pattern', LATCHED)
    assert wait_for(lambda: pub.get_subscription_count() > 0)

    too_long = np.column_stack([np.linspace(0, 1.0, 201), np.zeros(201)])
    pub.publish(path_msg(too_long))
    assert wait_for(lambda: node.errors == 1)
    assert wait_for(lambda: statuses and statuses[-1].status[0].level == DiagnosticStatus.ERROR)
    assert 'longer than the rod allows' in statuses[-1].status[0].message
    pub.publish(path_msg([[0, 0], [0.1, 0]]))
    assert wait_for(lambda: node.errors == 2)
    assert trajectories == [] and node.published == 0                 # nothing published for bad patterns

    th = np.linspace(0, 1.5, 80)
    xy = np.column_stack([0.15 * np.sin(th), 0.15 * (1 - np.cos(th))])
    pub.publish(path_msg(xy))
    assert wait_for(lambda: len(trajectories) == 1, timeout_s=20)
    # the status topic is delivered independently of the trajectory: it may arrive just after it
    assert wait_for(lambda: statuses[-1].status[0].level == DiagnosticStatus.OK)
    t, pos, quat = trajectory_from_path(trajectories[0])
    expected = plan_trajectory(xy, rod_description_from_dict({'length': 0.89, 'radius': 0.002, 'L_gb': 0.034}),
                               PlannerSettings())
    np.testing.assert_allclose(pos, expected.position, atol=1e-9)
    np.testing.assert_allclose(quat, expected.quaternion, atol=1e-9)
    np.testing.assert_allclose(t, expected.t, atol=1e-6)              # poses stamped along the trajectory
    assert trajectories[0].header.frame_id == 'table'


def test_start_parameter(ros_context):
    rod = [Parameter('length', value=0.89), Parameter('radius', value=0.002), Parameter('L_gb', value=0.034)]
    node = ros_context.add(GraspTrajectoryGenerator(context=ros_context.context, parameter_overrides=rod + [
        Parameter('start', value='tangent')]))
    assert node.settings.start == 'tangent'
    with pytest.raises(ValueError, match="parameter 'start'"):
        GraspTrajectoryGenerator(context=ros_context.context, parameter_overrides=rod + [
            Parameter('start', value='curved')])
