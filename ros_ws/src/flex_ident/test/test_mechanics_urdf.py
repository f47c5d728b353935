"""URDF -> serial chain: the project's Baxter arm, composite bodies, and clear errors on bad URDFs."""
from pathlib import Path

import mujoco
import numpy as np
import pytest

import flex_ident
from flex_ident.mechanics import tree_kinematics as tk
from flex_ident.mechanics.assembly import add_serial_arm
from flex_ident.mechanics.examples import SPATIAL_ARM_URDF, spatial_arm_urdf
from flex_ident.mechanics.model import ModelBuilder
from flex_ident.mechanics.urdf import UrdfError, load_urdf, serial_chain

BAXTER_URDF = Path(flex_ident.__file__).parent / 'data' / 'baxter_right_arm.urdf'
BAXTER_JOINTS = ['right_s0', 'right_s1', 'right_e0', 'right_e1', 'right_w0', 'right_w1', 'right_w2']


def arm_model(urdf_path, base, tip, joints):
    chain = serial_chain(load_urdf(urdf_path), base, tip)
    builder = ModelBuilder()
    coords = add_serial_arm(builder, chain, joints)
    builder.add_frame('ee', coords[-1], chain.tip_offset)
    return builder.build()


def ee_position(model, q):
    coord, off = model.frames['ee']
    _, p = tk.frame_pose(model.kernel(), np.asarray(q, float), coord, np.ascontiguousarray(off[:3, :3]),
                         np.ascontiguousarray(off[:3, 3]))
    return p


def test_baxter_chain_matches_published_numbers():
    chain = serial_chain(load_urdf(BAXTER_URDF), 'base', 'right_gripper')
    assert [j.name for j in chain.joints] == BAXTER_JOINTS
    assert chain.joints[0].mass_kg == pytest.approx(5.70044, rel=1e-6)
    assert all(j.damping == pytest.approx(0.7) for j in chain.joints)
    model = arm_model(BAXTER_URDF, 'base', 'right_gripper', BAXTER_JOINTS)
    # pinocchio's numbers for the published URDF (data/baxter_description/baxter_right_arm_params.md)
    np.testing.assert_allclose(ee_position(model, np.zeros(7)), [0.8151, -1.0101, 0.3210], atol=1e-4)
    np.testing.assert_allclose(ee_position(model, [0, -0.55, 0, 0.75, 0, 1.26, 0]), [0.6359, -0.8309, 0.1945],
                               atol=1e-4)


def test_spatial_arm_mass_matrix_and_gravity_match_mujoco_urdf_import(tmp_path):
    """Full inertia tensors, inertial rpy, fixed-joint merging, tilted axis: compare with MuJoCo's own importer."""
    path = spatial_arm_urdf(tmp_path / 'arm.urdf')
    model = arm_model(path, 'base', 'tip', ['j1', 'j2', 'j3'])
    mj = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(3)
    for _ in range(3):
        q = rng.uniform(-2, 2, 3)
        data.qpos[:] = q
        data.qvel[:] = 0
        mujoco.mj_forward(mj, data)
        M = np.zeros((3, 3))
        mujoco.mj_fullM(mj, data, M)
        n, nc = 3, len(model.coefficients)
        Lq, Lvv = np.zeros(n), np.zeros((n, n))
        tk.lagrangian_derivatives(model.kernel(), q, np.zeros(n), model.coef_values(), True, Lq, np.zeros(n),
                                  np.zeros((n, n)), np.zeros((n, n)), Lvv, np.zeros((n, nc)))
        np.testing.assert_allclose(Lvv, M, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(-Lq, data.qfrc_bias, rtol=1e-10, atol=1e-12)


def test_joint_order_of_the_experiment_is_the_configuration_order(tmp_path):
    path = spatial_arm_urdf(tmp_path / 'arm.urdf')
    a = arm_model(path, 'base', 'tip', ['j1', 'j2', 'j3'])
    b = arm_model(path, 'base', 'tip', ['j3', 'j1', 'j2'])
    q = np.array([0.3, -0.4, 1.1])
    np.testing.assert_allclose(ee_position(a, q), ee_position(b, q[[2, 0, 1]]), atol=1e-14)


def write(tmp_path, text, name='robot.urdf'):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize('edit, base, tip, message', [
    (lambda s: s.replace('<inertial><origin xyz="0.12 0.0 0.01" rpy="0 0.3 0"/><mass value="1.5"/>\n'
                         '      <inertia ixx="0.004" ixy="-0.0005" ixz="0.0008" iyy="0.020" iyz="0.0002" izz="0.018"/>'
                         '</inertial>', ''),
     'base', 'tip', 'no <inertial>'),
    (lambda s: s.replace('type="continuous"', 'type="floating"'), 'base', 'tip', 'type "floating"'),
    (lambda s: s, 'base', 'nowhere', 'tip_link "nowhere" is not a link'),
    (lambda s: s, 'l2', 'l1', 'is not below base_link'),
    (lambda s: s.replace('<mass value="2.0"/>', '<mass value="-2.0"/>'), 'base', 'tip', 'negative mass'),
    (lambda s: s.replace('<axis xyz="0.6 0 0.8"/>', '<axis xyz="0 0 0"/>'), 'base', 'tip', 'zero axis'),
    (lambda s: s.replace('ixx="0.030"', 'ixx="abc"'), 'base', 'tip', 'is not a number'),
    (lambda s: s.replace('</robot>', ''), 'base', 'tip', 'not valid XML'),
])
def test_bad_urdfs_raise_one_clear_error(tmp_path, edit, base, tip, message):
    path = write(tmp_path, edit(SPATIAL_ARM_URDF.replace('{damping}', '0.1')))
    with pytest.raises(UrdfError, match=message):
        serial_chain(load_urdf(path), base, tip)


def test_urdf_without_any_inertial_is_refused(tmp_path):
    import re
    text = re.sub(r'<inertial>.*?</inertial>', '', SPATIAL_ARM_URDF.replace('{damping}', '0'), flags=re.S)
    with pytest.raises(UrdfError, match='no <inertial> on the links moved by joint'):
        serial_chain(load_urdf(write(tmp_path, text)), 'base', 'tip')


def test_missing_urdf_file(tmp_path):
    with pytest.raises(UrdfError, match='does not exist'):
        load_urdf(tmp_path / 'none.urdf')
