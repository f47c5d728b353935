"""The closed loop for an arm alone, in the torque domain, on recordings made here with known effects: Pinocchio's
inverse dynamics of our Baxter URDF with one link heavier than the URDF says, per-joint friction of different sizes,
or nothing added (then nothing may be named). Written as contract bags and run through `flex-ident identify`."""
import json
from pathlib import Path

import numpy as np
import pytest

import flex_ident
from flex_ident.cli.main import main
from flex_ident.diagnosis.arm_torque import PinocchioArm
from robot_bridge.bagio.contract import JointRecording, write_joint_recording

URDF = Path(flex_ident.__file__).parent / 'data' / 'baxter_right_arm.urdf'
JOINTS = ['right_s0', 'right_s1', 'right_e0', 'right_e1', 'right_w0', 'right_w1', 'right_w2']
Q0 = np.array([0.0, -0.55, 0.0, 0.75, 0.0, 1.26, 0.0])


def make_recording(tmp_path, seconds=12.0, rate=200.0, heavier=None, viscous=None, coulomb=None, noise=0.02,
                   constant_effort=False, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * rate)) / rate
    freqs = rng.uniform(0.15, 0.6, size=(3, 7))
    phases = rng.uniform(0, 2 * np.pi, size=(3, 7))
    amp = np.array([0.5, 0.3, 0.5, 0.4, 0.6, 0.4, 0.8])
    w = 2 * np.pi * freqs
    q = Q0 + sum(amp / 3 * np.sin(w[k] * t[:, None] + phases[k]) for k in range(3))
    qd = sum(amp / 3 * w[k] * np.cos(w[k] * t[:, None] + phases[k]) for k in range(3))
    qdd = sum(-amp / 3 * w[k] ** 2 * np.sin(w[k] * t[:, None] + phases[k]) for k in range(3))
    arm = PinocchioArm(URDF, JOINTS, 'base')
    if heavier is not None:                           # the real arm's link is heavier than the URDF says
        link, factor = heavier
        jid = arm.model.getJointId(link)
        arm.model.inertias[jid].mass = arm.model.inertias[jid].mass * factor
    tau = arm.inverse_dynamics(q, qd, qdd)
    if viscous is not None:
        tau += np.asarray(viscous) * qd
    if coulomb is not None:
        tau += np.asarray(coulomb) * np.tanh(qd / 0.02)
    tau += noise * rng.normal(size=tau.shape)
    if constant_effort:
        tau[:] = 0.0
    write_joint_recording(tmp_path / 'bag', JointRecording(t, JOINTS, q + 1e-5 * rng.normal(size=q.shape), None,
                                                           tau, stamp0_ns=1_000_000_000))
    exp = tmp_path / 'arm.yaml'
    exp.write_text(f'arm:\n  urdf: {URDF}\n  base_link: base\n  tip_link: right_gripper\n  joints: {JOINTS}\n')
    return tmp_path / 'bag', exp


def run(bag, exp, out, *extra):
    code = main(['identify', '--bag', str(bag), '--experiment', str(exp), '--out', str(out), '--quiet', *extra])
    return code, (json.loads((out / 'report.json').read_text()) if (out / 'report.json').exists() else None)


def test_clean_arm_recording_names_no_effect(tmp_path):
    bag, exp = make_recording(tmp_path)
    code, report = run(bag, exp, tmp_path / 'out')
    assert code == 0
    assert report['effects_added'] == []
    assert report['error_after']['torque_rms_nm'] == pytest.approx(0.02, rel=0.3)   # the noise level is left
    assert set(report['error_before']['per_joint_nm']) == set(JOINTS)
    assert {'residual_per_joint.png', 'friction_signature.png'} <= set(report['plots'])


def test_heavier_link_and_per_joint_friction_are_found(tmp_path):
    coulomb = [0.8, 0.0, 0.5, 0.3, 0.0, 0.2, 0.1]                     # different sizes per joint
    bag, exp = make_recording(tmp_path, heavier=('right_e1', 1.6), coulomb=coulomb)
    code, report = run(bag, exp, tmp_path / 'out')
    assert code == 0
    keys = [e['key'] for e in report['effects_added']]
    assert 'inertial' in keys and 'coulomb' in keys, keys              # per joint, not the shared value
    assert 'delay' not in keys and 'coulomb_shared' not in keys
    assert report['error_after']['torque_rms_nm'] < 0.05 < 0.5 * report['error_before']['torque_rms_nm']
    assert any("inertial parameters" in w for w in report['warnings'])
    fitted = next(e for e in report['effects_added'] if e['key'] == 'coulomb')['parameters']
    for j, f in zip(JOINTS, coulomb):
        assert fitted[f'f_coulomb_{j}_nm'] == pytest.approx(f, abs=0.05)
    for eff in report['effects_added']:                                 # every effect lowered the validation error
        assert eff['error_after']['torque_rms_nm'] < eff['error_before']['torque_rms_nm']


def test_arm_only_bad_input(tmp_path, capsys):
    bag, exp = make_recording(tmp_path / 'a', constant_effort=True)
    code, report = run(bag, exp, tmp_path / 'a' / 'out')
    assert code == 2 and report is None
    assert 'effort is constant' in capsys.readouterr().err
    bag, exp = make_recording(tmp_path / 'b', seconds=0.6)
    code, report = run(bag, exp, tmp_path / 'b' / 'out')
    assert code == 2 and report is None and 'too short' in capsys.readouterr().err
    bag, exp = make_recording(tmp_path / 'c')
    exp.write_text(exp.read_text().replace('right_w2', 'right_w9'))
    code, report = run(bag, exp, tmp_path / 'c' / 'out')
    assert code == 2 and report is None and 'right_w9' in capsys.readouterr().err


def _one_error_line(capsys) -> str:
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith('flex-ident: error: '), lines
    return lines[0]


def test_arm_only_bad_input_more_cases(tmp_path, capsys):
    """A joint missing from the bag, a URDF link with a negative mass, a window too short to validate and a
    validation fraction outside its range: one error line naming the problem, exit 2, no report."""
    import re
    bag, exp = make_recording(tmp_path / 'a', seconds=3.0)
    from robot_bridge.bagio.contract import read_joint_recording
    rec = read_joint_recording(bag)
    keep = [i for i, n in enumerate(rec.names) if n != 'right_e1']
    write_joint_recording(tmp_path / 'a' / 'bag6', JointRecording(rec.t_s, [rec.names[i] for i in keep],
                                                                  rec.position[:, keep], None, rec.effort[:, keep],
                                                                  stamp0_ns=1_000_000_000))
    code, report = run(tmp_path / 'a' / 'bag6', exp, tmp_path / 'a' / 'out')
    assert code == 2 and report is None and 'right_e1' in _one_error_line(capsys)

    text = URDF.read_text()
    bad = re.sub(r'(<link name="right_lower_forearm">.*?<mass value=")([^"]+)"', r'\1-2.0"', text, count=1,
                 flags=re.S)
    assert bad != text
    (tmp_path / 'bad.urdf').write_text(bad)
    exp_bad = tmp_path / 'bad.yaml'
    exp_bad.write_text(exp.read_text().replace(str(URDF), str(tmp_path / 'bad.urdf')))
    code, report = run(bag, exp_bad, tmp_path / 'b' / 'out')
    line = _one_error_line(capsys)
    assert code == 2 and report is None and 'right_lower_forearm' in line and 'mass' in line

    exp_short = tmp_path / 'short.yaml'
    exp_short.write_text(exp.read_text() + 'identify:\n  window: [0.0, 0.5]\n')
    code, report = run(bag, exp_short, tmp_path / 'c' / 'out')
    assert code == 2 and report is None and 'short' in _one_error_line(capsys)

    code, report = run(bag, exp, tmp_path / 'd' / 'out', '--validation-fraction', '0.95')
    assert code == 2 and report is None and 'validation fraction' in _one_error_line(capsys)
