"""bag-tools: CSV import (presets, mapping YAML, errors), info, reindex."""
import json
from pathlib import Path

import numpy as np
import pytest

from robot_bridge.bagio.contract import read_joint_recording
from robot_bridge.bagio.csv_import import PRESETS
from robot_bridge.cli.bag_tools import main

SHARED = Path(__file__).resolve().parents[5] / 'shared' / 'data' / 'robot_torque'


def write_csv(path, header, rows):
    lines = ([','.join(header)] if header else []) + [','.join(f'{v:.9g}' for v in r) for r in rows]
    path.write_text('\n'.join(lines) + '\n')


def kinova_like(path, k=50):
    t = np.arange(k)
    pos = np.stack([np.linspace(6.0, 6.6, k) % (2 * np.pi)] + [np.full(k, 0.1 * j) for j in range(1, 7)], 1)
    vel = np.ones((k, 7)) * 0.5
    tau = np.arange(k * 7, dtype=float).reshape(k, 7)
    header = ['Time'] + [f'Position{i}' for i in range(1, 8)] + [f'Velocity{i}' for i in range(1, 8)] \
        + [f'Torque{i}' for i in range(1, 8)] + ['Temp1']
    write_csv(path, header, np.column_stack([t, pos, vel, tau, np.zeros(k)]))
    return pos, tau


def test_kinova_preset_converts_sample_index_and_unwraps(tmp_path, capsys):
    pos, tau = kinova_like(tmp_path / 'k.csv')
    assert main(['import-csv', str(tmp_path / 'k.csv'), '--out', str(tmp_path / 'bag'),
                 '--preset', 'kinova_gen3']) == 0
    rec = read_joint_recording(tmp_path / 'bag')
    assert rec.names == PRESETS['kinova_gen3']['joints']
    np.testing.assert_allclose(rec.t_s, np.arange(50) / 1000.0, atol=1e-9)
    np.testing.assert_allclose(rec.position[:, 0], np.linspace(6.0, 6.6, 50), atol=1e-7)  # unwrapped
    np.testing.assert_allclose(rec.effort, tau)


def test_mapping_yaml_with_degrees_and_separate_files(tmp_path):
    k = 20
    write_csv(tmp_path / 'q.csv', None, np.column_stack([np.arange(k) * 10.0, -np.arange(k) * 1.0]))
    write_csv(tmp_path / 'tau.csv', None, np.column_stack([np.ones(k + 1), 2 * np.ones(k + 1)]))
    write_csv(tmp_path / 'time.csv', None, (np.arange(k)[:, None] * 5.0))
    (tmp_path / 'map.yaml').write_text(
        "header: false\ntime: {column: 0, unit: ms}\ntime_file: time.csv\njoints: [a, b]\n"
        "position: {columns: [0, 1], unit: deg}\neffort: {columns: [0, 1], unit: N m}\neffort_file: tau.csv\n")
    assert main(['import-csv', str(tmp_path / 'q.csv'), '--out', str(tmp_path / 'bag'),
                 '--map', str(tmp_path / 'map.yaml'), '--storage', 'sqlite3']) == 0
    rec = read_joint_recording(tmp_path / 'bag')
    np.testing.assert_allclose(rec.t_s, np.arange(k) * 0.005, atol=1e-9)
    np.testing.assert_allclose(rec.position[:, 0], np.deg2rad(np.arange(k) * 10.0))
    assert rec.velocity is None and rec.effort.shape == (k, 2)


@pytest.mark.parametrize('setup, message', [
    (lambda p: p.write_text(''), 'is empty'),
    (lambda p: write_csv(p, ['t_s', 'x'], [[0, 1]]), "column 'Time' not in"),
])
def test_bad_csv_gives_one_clear_line_and_no_bag(tmp_path, capsys, setup, message):
    setup(tmp_path / 'bad.csv')
    assert main(['import-csv', str(tmp_path / 'bad.csv'), '--out', str(tmp_path / 'bag'),
                 '--preset', 'kinova_gen3']) == 2
    stderr = capsys.readouterr().err
    # the tool's own output is one line; other lines can only come from the garbage collector finalising an earlier
    # test's rclpy objects in this process ("The following exception was never retrieved: ...", seen once in CI)
    err = [line for line in stderr.strip().splitlines() if line.startswith('bag-tools')]
    assert len(err) == 1 and message in err[0] and 'Traceback' not in stderr
    assert not (tmp_path / 'bag').exists()


def test_unknown_preset_is_named(tmp_path, capsys):
    kinova_like(tmp_path / 'k.csv')
    assert main(['import-csv', str(tmp_path / 'k.csv'), '--out', str(tmp_path / 'b'), '--preset', 'ur5']) == 2
    assert "unknown preset 'ur5'" in capsys.readouterr().err


def test_info_json(tmp_path, capsys):
    kinova_like(tmp_path / 'k.csv')
    main(['import-csv', str(tmp_path / 'k.csv'), '--out', str(tmp_path / 'bag'), '--preset', 'kinova_gen3'])
    capsys.readouterr()
    assert main(['info', str(tmp_path / 'bag'), '--json']) == 0
    info = json.loads(capsys.readouterr().out)
    js = info['topics']['/joint_states']
    assert js['count'] == 50 and abs(js['rate_hz'] - 1000) < 1e-6 and len(info['joint_names']) == 7


@pytest.mark.parametrize('preset, rel', [
    ('kinova_gen3', 'kinova_gen3_chiha2024/RunTrajectory1.csv'),
    ('franka_gaz2019', 'franka_panda_gaz2019/panda_exciting_traj1.csv'),
    ('kuka_lwr4', 'kuka_lwr4_flobaroid/kuka_lwr4_measurements_1.csv'),
    ('schunk_liu2018', 'schunk_6dof_liu_althoff2018/measurement_1/trajectory.csv'),
])
def test_presets_on_the_shared_logs(tmp_path, capsys, preset, rel):
    """Each preset against the file read independently with numpy: joint names, units (rad, rad/s, N m, seconds
    from 0), Kinova's 1 kHz sample index and unwrapped positions, Schunk's three files with the extra state row."""
    if not (SHARED / rel).exists():
        pytest.skip('shared robot_torque data not present')
    assert main(['import-csv', str(SHARED / rel), '--out', str(tmp_path / 'bag'), '--preset', preset]) == 0
    printed = capsys.readouterr().out
    rec = read_joint_recording(tmp_path / 'bag', require_effort=True)
    assert rec.names == PRESETS[preset]['joints']
    if preset == 'schunk_liu2018':
        traj = np.loadtxt(SHARED / rel, delimiter=',')
        tau = np.loadtxt(SHARED / rel.replace('trajectory', 'input'), delimiter=',')
        t = np.loadtxt(SHARED / rel.replace('trajectory', 'time'), delimiter=',')
        assert len(traj) == len(tau) + 1 == len(rec.t_s) + 1         # the last state row has no torque: dropped
        assert 'dropped' in printed or 'drop' in printed
        pos, vel, t = traj[:-1, :6], traj[:-1, 6:], t[:-1]
    else:
        data = np.genfromtxt(SHARED / rel, delimiter=',', names=True)
        cols = data.dtype.names
        if preset == 'kinova_gen3':
            t = data['Time'] / 1000.0
            pos = np.stack([data[f'Position{i}'] for i in range(1, 8)], 1)
            vel = np.stack([data[f'Velocity{i}'] for i in range(1, 8)], 1)
            tau = np.stack([data[f'Torque{i}'] for i in range(1, 8)], 1)
        else:
            t = data['t_s']
            pos = np.stack([data[c] for c in cols if c.startswith('q')], 1)
            vel = np.stack([data[c] for c in cols if c.startswith('dq')], 1)
            tau = np.stack([data[c] for c in cols if c.startswith('tau')], 1)
    np.testing.assert_allclose(rec.t_s, t - t[0], atol=2e-9)
    if preset == 'kinova_gen3':
        assert np.all(np.abs(np.diff(rec.position, axis=0)) < 1.0)      # unwrapped: no 2 pi jumps left
        np.testing.assert_allclose(np.mod(rec.position - pos + np.pi, 2 * np.pi) - np.pi, 0, atol=1e-9)
        assert 'unwrapped' in printed
    else:
        np.testing.assert_allclose(rec.position, pos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rec.velocity, vel, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rec.effort, tau, rtol=0, atol=1e-12)


def test_window_covering_the_whole_recording_is_accepted_but_a_longer_one_is_not(tmp_path):
    from robot_bridge.bagio.contract import JointRecording, write_joint_recording
    from robot_bridge.bagio.raw import BagError
    k = 2000
    rec = JointRecording(np.arange(k) * 0.01, ['a'], np.zeros((k, 1)), None, np.zeros((k, 1)))
    write_joint_recording(tmp_path / 'b', rec)
    assert len(read_joint_recording(tmp_path / 'b', window=(0.0, 20.0)).t_s) == k
    with pytest.raises(BagError, match='shorter than the window'):
        read_joint_recording(tmp_path / 'b', window=(0.0, 20.5))
