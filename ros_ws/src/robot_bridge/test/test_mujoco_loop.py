"""The MuJoCo loop simulator as a specification: contract geometry, closed-form spring physics, energy, welds,
static start, sensor effects, and the bag it writes."""
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pytest

from robot_bridge.bagio.contract import read_joint_recording
from robot_bridge.sim import mujoco_loop
from robot_bridge.sim.experiment import load_experiment
from robot_bridge.sim.mjcf_builder import add_loop_link, cylinder_link_inertia
from robot_bridge.sim.motion import SumOfSinesMotion, reference
from robot_bridge.sim.mujoco_loop import LoopSimulator, simulate_loop_experiment
from robot_bridge.sim.transforms import matrix_rpy, transform

URDF = Path(__file__).resolve().parents[2] / 'flex_ident' / 'flex_ident' / 'data' / 'baxter_right_arm.urdf'
EXAMPLES = Path(__file__).resolve().parents[4] / 'bags'
ARM_JOINTS = ['right_s0', 'right_s1', 'right_e0', 'right_e1', 'right_w0', 'right_w1', 'right_w2']
SHORT_MOTION = {'rest_s': 1.0, 'ramp_s': 1.0, 'end_rest_s': 0.5}


def experiment(links=6, clamp=None, joints=ARM_JOINTS, gravity=9.81):
    """A contract experiment dict: the gripper points down over the clamp (the shipped example's geometry)."""
    clamp = clamp or {'xyz': [0.6, -0.8, -0.3], 'rpy': [np.pi, 0.0, 0.75 * np.pi]}
    return {'arm': {'urdf': str(URDF), 'base_link': 'base', 'tip_link': 'right_gripper', 'joints': list(joints)},
            'object': {'type': 'loop', 'links': links, 'radius': 0.25, 'mass': 0.6, 'tube_radius': 0.02,
                       'grasp': {'xyz': [0, 0, 0], 'rpy': [0, 0, 0]}, 'clamp': clamp},
            'gravity': gravity}


def clamp_below(sim: LoopSimulator, q_arm, radius=0.25) -> dict:
    """The clamp pose C with G(q_arm) = C T(0, 0, -2R)."""
    c = sim.arm_grasp_pose(q_arm) @ transform(xyz=(0.0, 0.0, 2.0 * radius))
    return {'xyz': c[:3, 3].tolist(), 'rpy': matrix_rpy(c[:3, :3]).tolist()}


@pytest.mark.parametrize('links', [6, 12])
def test_rest_shape_satisfies_every_constraint_when_grasp_is_two_radii_above_clamp(links):
    q = np.array([0.2, -0.4, 0.3, 1.0, -0.5, 0.9, 0.7])   # any pose: the loop hangs wherever the gripper points
    sim = LoopSimulator(load_experiment(experiment(links)))
    sim = LoopSimulator(load_experiment(experiment(links, clamp=clamp_below(sim, q))))
    sim.set_state(q)                                       # all loop angles 0: the undeformed N-gon
    dist, ang = sim.weld_residual()
    assert dist < 1e-12 and ang < 1e-7
    assert np.max(np.abs(sim.data.efc_pos[:12])) < 1e-12  # MuJoCo's own 12 weld residuals
    g = sim.arm_grasp_pose(q)
    radius = 0.25
    for side, sign in (('left', 1), ('right', -1)):       # vertices j = 0, +-1, ... in G (contract formula)
        for k in range(1, links // 2 + 1):
            j = sign * (k - 1)
            vertex = np.linalg.solve(g, np.r_[sim.data.xpos[sim.model.body(f'loop_{side}_{k}').id], 1.0])[:3]
            expected = [radius * np.sin(2 * np.pi * j / links), 0.0, radius - radius * np.cos(2 * np.pi * j / links)]
            np.testing.assert_allclose(vertex, expected, atol=1e-12)


def single_link(k_theta, k_phi, gravity, damping=0.0, length=0.13, mass=0.05, radius=0.02):
    """One loop link (the builder's own code) on a fixed base: joint at the origin, link along +x."""
    root = ET.Element('mujoco')
    ET.SubElement(root, 'compiler', angle='radian', inertiafromgeom='false')
    ET.SubElement(root, 'option', timestep='0.0005', integrator='RK4', gravity=' '.join(map(str, gravity)))
    add_loop_link(ET.SubElement(root, 'worldbody'), 'link', np.eye(4), length, mass, radius, k_theta, k_phi,
                  damping)
    model = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding='unicode'))
    return model, mujoco.MjData(model)


def test_spring_torque_sign_and_scale_match_closed_form():
    k_theta, k_phi, m, l, g = 5.0, 3.0, 0.05, 0.13, 9.81
    model, data = single_link(k_theta, k_phi, (0, 0, 0))
    data.qpos[:] = [0.1, -0.2]
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.qfrc_passive, [-k_theta * 0.1, k_phi * 0.2], rtol=1e-12)
    # gravity along -z droops the link about +y (theta > 0): k theta = m g (l/2) cos(theta)
    model, data = single_link(k_theta, k_phi, (0, 0, -g), damping=0.05)
    for _ in range(20000):
        mujoco.mj_step(model, data)
    theta = data.qpos[0]
    assert theta > 0 and abs(data.qpos[1]) < 1e-9
    assert k_theta * theta == pytest.approx(m * g * l / 2 * np.cos(theta), rel=1e-6)
    # gravity along -y bends it about z the other way (phi < 0): k phi = -m g (l/2) cos(phi)
    model, data = single_link(k_theta, k_phi, (0, -g, 0), damping=0.05)
    for _ in range(20000):
        mujoco.mj_step(model, data)
    phi = data.qpos[1]
    assert phi < 0 and k_phi * phi == pytest.approx(-m * g * l / 2 * np.cos(phi), rel=1e-6)


def test_small_oscillation_period_is_that_of_a_solid_cylinder_on_a_torsional_spring():
    k, m, l, r = 5.0, 0.05, 0.13, 0.02
    model, data = single_link(k, k, (0, 0, 0), length=l, mass=m, radius=r)
    inertia_end = cylinder_link_inertia(m, r, l)[1] + m * (l / 2) ** 2
    period = 2 * np.pi * np.sqrt(inertia_end / k)
    data.qpos[0] = 1e-3
    crossings, prev = [], data.qpos[0]
    while data.time < 10 * period:
        mujoco.mj_step(model, data)
        now = data.qpos[0]
        if prev > 0 >= now:   # downward zero crossing, interpolated within the step
            crossings.append(data.time - model.opt.timestep * now / (now - prev))
        prev = now
    assert np.mean(np.diff(crossings)) == pytest.approx(period, rel=1e-4)


def _constraint_consistent(sim, qvel):
    """Project qvel onto the welds' null space (velocities the closed loop can have)."""
    m, d = sim.model, sim.data
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    rows = []
    for end, _ in sim.end_sites:
        jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        mujoco.mj_jacSite(m, d, jacp, jacr, end)
        rows += [jacp, jacr]
    jac = np.vstack(rows)
    return qvel - np.linalg.pinv(jac) @ (jac @ qvel)


@pytest.mark.parametrize('case', ['whole arm, no gravity', 'wrist roll only, gravity'])
def test_energy_is_conserved_without_damping(case):
    if case == 'whole arm, no gravity':
        exp = experiment(6, gravity=0.0)
        sim = LoopSimulator(load_experiment(exp))
        q0, speed = sim.solve_start_pose(), 0.5
    else:   # the other arm joints locked at 0: loop and wrist swing under gravity
        sim = LoopSimulator(load_experiment(experiment(6, joints=['right_w2'])))
        sim = LoopSimulator(load_experiment(experiment(6, joints=['right_w2'], clamp=clamp_below(sim, [0.0]))))
        q0, speed = np.zeros(1), 3.0
    m, d = sim.model, sim.data
    m.dof_damping[:] = 0.0                             # URDF damping off too: a conservative system
    sim.set_state(q0)
    d.qvel[:] = _constraint_consistent(sim, speed * np.random.default_rng(0).normal(size=m.nv))
    mujoco.mj_forward(m, d)
    energy0, kinetic0 = d.energy.sum(), d.energy[1]
    drift = []
    for i in range(2000):                              # 2 s
        mujoco.mj_step(m, d)
        if i % 20 == 0:
            mujoco.mj_forward(m, d)
            drift.append(d.energy.sum() - energy0)
    assert kinetic0 > 1e-4
    assert np.max(np.abs(drift)) < 1e-3 * kinetic0     # welds dissipate only a trace
    assert sim.weld_residual()[0] < 1e-6


@pytest.fixture(scope='module')
def short_run():
    return simulate_loop_experiment(experiment(6), duration_s=3.5, k_theta=5.0, k_phi=3.0, motion=SHORT_MOTION)


def test_recording_starts_in_static_equilibrium(short_run):
    rec = short_run
    still = rec.t_s < 0.5 + 1e-9
    assert rec.info['settled'] and len(rec.t_s) == 350
    assert np.max(np.abs(rec.velocity[still])) < 1e-5
    assert np.ptp(rec.position[still], axis=0).max() < 1e-7
    assert np.ptp(rec.loop_position[still], axis=0).max() < 1e-6
    assert np.ptp(rec.effort[still], axis=0).max() < 1e-4
    assert np.max(np.abs(rec.loop_position[0])) > 1e-3    # gravity deformed the loop: not the rest shape
    assert np.max(np.abs(rec.velocity)) > 0.05            # and then it moved


def test_weld_residual_stays_small_while_the_arm_moves(short_run):
    assert short_run.info['max_weld_residual_m'] < 1e-4
    assert short_run.info['max_weld_residual_rad'] < 1e-3
    assert short_run.info['saturated_steps'] == 0


def test_reference_is_still_at_both_ends_and_smooth():
    t = np.arange(0, 10.0001, 0.001)
    q, qd, qdd = reference(t, np.zeros(7), 10.0, SumOfSinesMotion())
    assert np.all(q[t <= 1.0] == 0) and np.all(qd[t <= 1.0] == 0) and np.all(qdd[t <= 1.0] == 0)
    np.testing.assert_allclose(q[t >= 9.5], 0.0, atol=1e-15)
    np.testing.assert_allclose(np.gradient(q, t, axis=0)[5:-5], qd[5:-5], atol=1e-5)
    np.testing.assert_allclose(np.gradient(qd, t, axis=0)[5:-5], qdd[5:-5], atol=1e-3)


def test_sensor_effects_noise_and_arm_only():
    effects = {'effort_bias_nm': [0.5, -0.3, 0, 0, 0, 0, 0.1], 'effort_gain': 1.1, 'position_delay_s': 0.02}
    clean = simulate_loop_experiment(experiment(6), 3.5, motion=SHORT_MOTION, with_object=False)
    rec = simulate_loop_experiment(experiment(6), 3.5, motion=SHORT_MOTION, with_object=False, effects=effects)
    assert rec.loop_position.shape == (350, 0) and not rec.info['with_object']
    np.testing.assert_allclose(rec.effort, 1.1 * rec.effort_true + effects['effort_bias_nm'], atol=1e-12)
    np.testing.assert_allclose(rec.position[2:], rec.arm_position_true[:-2], atol=1e-12)   # 20 ms = 2 samples
    np.testing.assert_allclose(rec.arm_position_true, clean.arm_position_true, atol=1e-12)  # sensors only
    noise = {'position_rad': 1e-3, 'effort_nm': 0.1}
    a = simulate_loop_experiment(experiment(6), 3.5, motion=SHORT_MOTION, with_object=False, noise=noise, seed=3)
    b = simulate_loop_experiment(experiment(6), 3.5, motion=SHORT_MOTION, with_object=False, noise=noise, seed=3)
    np.testing.assert_array_equal(a.position, b.position)
    assert np.std(a.position - a.arm_position_true) == pytest.approx(1e-3, rel=0.1)
    assert np.std(a.effort - a.effort_true) == pytest.approx(0.1, rel=0.1)


def test_loop_damping_effect_is_physical():
    damped = simulate_loop_experiment(experiment(6), 3.5, motion=SHORT_MOTION, effects={'loop_damping_nms': 0.05})
    clean = simulate_loop_experiment(experiment(6), 3.5, motion=SHORT_MOTION)
    np.testing.assert_allclose(damped.effort[:50], clean.effort[:50], atol=1e-6)   # same static start
    assert np.max(np.abs(damped.effort - clean.effort)) > 1e-3


def test_command_line_writes_a_contract_bag(tmp_path):
    import yaml
    exp = tmp_path / 'experiment.yaml'
    exp.write_text(yaml.safe_dump(experiment(6)))
    out = tmp_path / 'bag'
    assert mujoco_loop.main(['--experiment', str(exp), '--out', str(out), '--duration', '2', '--k-theta', '4',
                             '--no-object', '--truth', str(tmp_path / 'truth'), '--amplitude-scale', '0.5']) == 1
    # 2 s is too short for the default rest + ramps: a clear error, no bag
    assert not out.exists()
    assert mujoco_loop.main(['--experiment', str(exp), '--out', str(out), '--duration', '6', '--k-theta', '4',
                             '--noise-position', '1e-4', '--truth', str(tmp_path / 'truth')]) == 0
    rec = read_joint_recording(out, joints=ARM_JOINTS, require_effort=True)
    assert rec.position.shape == (600, 7) and rec.velocity.shape == (600, 7)
    np.testing.assert_allclose(np.diff(rec.t_s), 0.01, atol=1e-9)
    truth = np.load(tmp_path / 'truth.npz')
    assert truth['loop_position'].shape == (600, 12)
    np.testing.assert_allclose(rec.position, truth['arm_position'], atol=1e-3)


@pytest.mark.parametrize('name, links, samples', [('example_loop12', 12, 2000), ('example_loop6', 6, 1000)])
def test_shipped_example_bags_match_their_experiment_and_truth(name, links, samples):
    import json
    folder = EXAMPLES / name
    exp = load_experiment(folder / 'experiment.yaml')
    assert exp.loop.links == links and exp.arm.urdf_path.is_file()
    assert exp.arm.urdf_path.read_text() == URDF.read_text()          # the copy is our current URDF
    rec = read_joint_recording(folder / 'bag', joints=ARM_JOINTS, require_effort=True)
    truth = json.loads((folder / 'truth.json').read_text())
    assert len(rec.t_s) == samples and (truth['k_theta'], truth['k_phi']) == (5.0, 3.0)
    still = rec.t_s < 0.5
    assert np.max(np.abs(rec.velocity[still])) < 6 * truth['noise']['velocity_rad_s']
    assert np.ptp(rec.position[still], axis=0).max() < 12 * truth['noise']['position_rad']
    sim = LoopSimulator(exp)
    grasp = sim.arm_grasp_pose(np.array(truth['q_start_rad']))
    np.testing.assert_allclose(grasp, exp.loop.rest_grasp(), atol=1e-9)   # the loop closes undeformed
    assert grasp[2, 2] < -0.999                                            # gripper points down


@pytest.mark.parametrize('values, expected', [(['0.3'], 0.3), (['0.1', '0.2', '0.3', '0.4', '0.5', '0.6', '0.7'],
                                                               [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7])])
def test_cli_friction_takes_one_value_or_one_per_joint(monkeypatch, tmp_path, values, expected):
    """--arm-coulomb / --arm-viscous: one value for every joint (as before) or one per arm joint."""
    seen = {}

    def fake(*args, effects=None, **kwargs):
        seen['effects'] = effects
        raise ValueError('stop here')

    monkeypatch.setattr(mujoco_loop, 'simulate_loop_experiment', fake)
    assert mujoco_loop.main(['--experiment', 'e.yaml', '--out', str(tmp_path / 'o'), '--arm-coulomb', *values,
                             '--arm-viscous', *values]) == 1
    assert seen['effects'].arm_coulomb_nm == expected and seen['effects'].arm_viscous_nms == expected
