"""The identification flow as a graph: bag_player (fake hardware; or a real arm / sim_arm publishing /joint_states)
-> joint_state_logger (closes the bag when the replay ends, announces it) -> stiffness_identifier (closed loop).

    ros2 launch flex_ident identification.launch.py bag:=bags/example_loop12/bag \
        experiment:=bags/example_loop12/experiment.yaml out:=out/identification

Not exercised by the tests here (no `launch` package in reach); scripts/demo.py composes the same nodes in one
process.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    arg = LaunchConfiguration
    return LaunchDescription([
        DeclareLaunchArgument('bag', description='rosbag2 to replay'),
        DeclareLaunchArgument('experiment', description='experiment YAML'),
        DeclareLaunchArgument('out', default_value='identification'),
        DeclareLaunchArgument('recording', default_value='recording', description='bag the logger writes'),
        DeclareLaunchArgument('rate', default_value='1.0'),
        DeclareLaunchArgument('diagnose', default_value='true', description='the closed loop'),
        Node(package='flex_ident', executable='stiffness_identifier', parameters=[{
            'experiment': arg('experiment'), 'out': arg('out'), 'diagnose': arg('diagnose'),
            'recorded_topic': '/joint_state_logger/recorded'}]),
        Node(package='flex_ident', executable='joint_state_logger', parameters=[{
            'output': arg('recording'), 'topics': ['/joint_states'], 'close_after_idle_s': 1.0}]),
        Node(package='robot_bridge', executable='bag_player', parameters=[{
            'bag': arg('bag'), 'rate': arg('rate'), 'wait_for_subscribers': 10.0}]),
    ])
