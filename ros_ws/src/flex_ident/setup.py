from glob import glob

from setuptools import find_packages, setup

package_name = 'flex_ident'

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
    description='Flexible-object stiffness identification: variational-integrator model, discrete adjoint, logger and identifier nodes.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'joint_state_logger = flex_ident.nodes.joint_state_logger:main',
            'stiffness_identifier = flex_ident.nodes.stiffness_identifier:main',
            'flex-ident = flex_ident.cli.main:main',
        ],
    },
)
