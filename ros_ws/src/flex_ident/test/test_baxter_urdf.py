"""The project's Baxter right-arm URDF (flex_ident/data/baxter_right_arm.urdf) against the published numbers.

Checks use only xml.etree and numpy (no simulator): chain structure, joint data, inertial validity, total mass, and
forward kinematics at the two check poses published with the parameters table.
"""
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

URDF = Path(__file__).resolve().parents[1] / 'flex_ident' / 'data' / 'baxter_right_arm.urdf'
ARM = ['right_s0', 'right_s1', 'right_e0', 'right_e1', 'right_w0', 'right_w1', 'right_w2']
LIMITS = {  # lower, upper, effort, velocity (published)
    'right_s0': (-1.70167993878, 1.70167993878, 50.0, 1.5), 'right_s1': (-2.147, 1.047, 100.0, 1.5),
    'right_e0': (-3.05417993878, 3.05417993878, 50.0, 1.5), 'right_e1': (-0.05, 2.618, 50.0, 1.5),
    'right_w0': (-3.059, 3.059, 15.0, 4.0), 'right_w1': (-1.57079632679, 2.094, 15.0, 4.0),
    'right_w2': (-3.059, 3.059, 15.0, 4.0)}


@pytest.fixture(scope='module')
def robot():
    return ET.parse(URDF).getroot()


def floats(text):
    return np.array([float(v) for v in text.split()])


def rpy_matrix(r, p, y):
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


def chain(robot, base='base', tip='right_gripper'):
    by_child = {j.find('child').get('link'): j for j in robot.findall('joint')}
    joints, link = [], tip
    while link != base:
        joints.append(by_child[link])
        link = joints[-1].find('parent').get('link')
    return joints[::-1]


def forward_kinematics(robot, q):
    """Tip pose (4x4) in the base frame for arm angles q (URDF: origin, then rotation about the joint z axis)."""
    pose, angles = np.eye(4), dict(zip(ARM, q))
    for j in chain(robot):
        o = j.find('origin')
        step = np.eye(4)
        step[:3, :3], step[:3, 3] = rpy_matrix(*floats(o.get('rpy'))), floats(o.get('xyz'))
        pose = pose @ step
        if j.get('type') == 'revolute':
            c, s = np.cos(angles[j.get('name')]), np.sin(angles[j.get('name')])
            pose = pose @ np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    return pose


def test_serial_chain_from_base_to_gripper(robot):
    joints = chain(robot)
    assert [j.get('name') for j in joints if j.get('type') != 'fixed'] == ARM
    assert [j.get('name') for j in joints if j.get('type') == 'fixed'] == [
        'torso_t0', 'right_torso_arm_mount', 'right_hand', 'right_gripper_base', 'right_endpoint']
    assert len(robot.findall('joint')) == len(joints)            # nothing hangs off the chain
    assert robot.find('.//mesh') is None and robot.find('.//gravity') is None
    assert robot.find('.//visual') is None and robot.find('.//collision') is None


@pytest.mark.parametrize('name', ARM)
def test_arm_joint_axis_limits_and_damping(robot, name):
    j = robot.find(f"joint[@name='{name}']")
    assert j.get('type') == 'revolute'
    np.testing.assert_array_equal(floats(j.find('axis').get('xyz')), [0, 0, 1])
    lim = j.find('limit')
    assert tuple(float(lim.get(k)) for k in ('lower', 'upper', 'effort', 'velocity')) == LIMITS[name]
    assert float(j.find('dynamics').get('damping')) == 0.7
    assert float(j.find('dynamics').get('friction')) == 0.0


def test_inertials_are_physical_and_mass_matches_the_published_total(robot):
    moving = 0.0
    for link in robot.findall('link'):
        inertial = link.find('inertial')
        if inertial is None:
            assert link.get('name') == 'base'
            continue
        i = {k: float(v) for k, v in inertial.find('inertia').attrib.items()}
        tensor = np.array([[i['ixx'], i['ixy'], i['ixz']], [i['ixy'], i['iyy'], i['iyz']],
                           [i['ixz'], i['iyz'], i['izz']]])
        principal = np.linalg.eigvalsh(tensor)
        assert principal.min() > 0, link.get('name')
        assert principal.sum() - 2 * principal.max() >= -1e-12, link.get('name')   # triangle inequality
        mass = float(inertial.find('mass').get('value'))
        if link.get('name') not in ('base', 'torso') and mass > 1e-3:
            moving += mass
    assert moving == pytest.approx(19.71082, abs=1e-9)   # s0..hand, published


@pytest.mark.parametrize('q, position', [
    ((0, 0, 0, 0, 0, 0, 0), (0.8151, -1.0101, 0.3210)),
    ((0, -0.55, 0, 0.75, 0, 1.26, 0), (0.6359, -0.8309, 0.1945)),
])
def test_gripper_position_matches_the_published_check_poses(robot, q, position):
    pose = forward_kinematics(robot, q)
    np.testing.assert_allclose(pose[:3, 3], position, atol=6e-5)


def test_gripper_points_down_in_the_nominal_pose(robot):
    z_axis = forward_kinematics(robot, (0, -0.55, 0, 0.75, 0, 1.26, 0))[:3, 2]
    assert z_axis[2] < -0.99
