from glob import glob

from setuptools import find_packages, setup

package_name = 'rod_deploy'

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
    description='Rod deployment: discrete elastic rods, optimal grasp, neural controller, planning and pattern perception.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'pattern_perception = rod_deploy.nodes.pattern_perception:main',
            'grasp_trajectory_generator = rod_deploy.nodes.grasp_trajectory_generator:main',
            'deployment_monitor = rod_deploy.nodes.deployment_monitor:main',
            'rod-deploy = rod_deploy.cli.main:main',
        ],
    },
)
