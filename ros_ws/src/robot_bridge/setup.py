from glob import glob

from setuptools import find_packages, setup

package_name = 'robot_bridge'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['data/*', 'data/**/*']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='Flexible-object robotics maintainers',
    maintainer_email='maintainers@flexible-robotics.invalid',
    description='Fake hardware (bag replay), bag tools and the arm-command bridge.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'bag_player = robot_bridge.nodes.bag_player:main',
            'bag-tools = robot_bridge.cli.bag_tools:main',
            'robot-bridge = robot_bridge.cli.robot_bridge_cli:main',
            'arm_command_bridge = robot_bridge.nodes.arm_command_bridge:main',
            'sim_arm = robot_bridge.nodes.sim_arm:main',
        ],
    },
)
