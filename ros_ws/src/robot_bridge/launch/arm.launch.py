"""The arm alone: sim_arm (fake hardware) and arm_command_bridge (gripper trajectory -> joint trajectory).

    ros2 launch robot_bridge arm.launch.py trajectory_csv:=out/traj.csv

Not exercised by the tests here (no `launch` package in reach).
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('trajectory_csv', default_value='', description='gripper CSV to execute once'),
        DeclareLaunchArgument('rate_hz', default_value='100.0'),
        Node(package='robot_bridge', executable='sim_arm', parameters=[{'rate_hz': LaunchConfiguration('rate_hz')}]),
        Node(package='robot_bridge', executable='arm_command_bridge',
             parameters=[{'trajectory_csv': LaunchConfiguration('trajectory_csv')}]),
    ])
