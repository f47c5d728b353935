"""The deployment flow as a graph: /deploy_request (sensor_msgs/Image of a drawn pattern) -> pattern_perception ->
grasp_trajectory_generator -> arm_command_bridge -> sim_arm (MuJoCo Baxter; with use_sim_arm:=false a real arm's
controller on /arm_controller/joint_trajectory), and deployment_monitor (/deploy_result, /deployed_shape,
/deploy_markers).

    ros2 launch rod_deploy deployment.launch.py rod_yaml:=out/rod.yaml m_per_px:=0.0005

Not exercised by the tests here (no `launch` package in reach); scripts/demo.py composes the same nodes in one
process.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    arg = LaunchConfiguration
    rod = {'rod_yaml': arg('rod_yaml')}
    return LaunchDescription([
        DeclareLaunchArgument('rod_yaml', description='rod description YAML (CONTRACTS.md section 4)'),
        DeclareLaunchArgument('m_per_px', default_value='0.0005', description='table metres per image pixel'),
        DeclareLaunchArgument('out', default_value='deployments'),
        DeclareLaunchArgument('use_sim_arm', default_value='true'),
        Node(package='robot_bridge', executable='sim_arm', condition=IfCondition(arg('use_sim_arm'))),
        Node(package='robot_bridge', executable='arm_command_bridge'),
        Node(package='rod_deploy', executable='pattern_perception', parameters=[{'m_per_px': arg('m_per_px')}]),
        Node(package='rod_deploy', executable='grasp_trajectory_generator', parameters=[rod]),
        Node(package='rod_deploy', executable='deployment_monitor', parameters=[{**rod, 'out': arg('out')}]),
    ])
