"""stiffness_identifier as a user runs it: the node as a process from its console script, a REAL identification
(no fake), driven by `flex-ident request` (a second process) and by ``run_on_start``; report.json checked."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

BIN = os.path.dirname(sys.executable)
EXAMPLE = Path(__file__).resolve().parents[4] / 'bags' / 'example_loop6'


def _node(*params):
    args = [os.path.join(BIN, 'stiffness_identifier'), '--ros-args']
    for p in params:
        args += ['-p', p]
    return subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _check_report(report, out):
    on_disk = json.loads((out / 'report.json').read_text())
    assert on_disk['parameters'] == pytest.approx(report['parameters'])
    assert report['parameters']['k_theta'] == pytest.approx(5.0, rel=0.005)    # the truth of the example bag
    assert report['parameters']['k_phi'] == pytest.approx(3.0, rel=0.005)
    assert report['error_after']['ee_rms_m'] < 0.1 * report['error_before']['ee_rms_m']


def test_request_client_gets_the_real_report_from_the_node(tmp_path):
    node = _node()
    try:
        client = subprocess.run(
            [os.path.join(BIN, 'flex-ident'), 'request', '--bag', str(EXAMPLE / 'bag'),
             '--experiment', str(EXAMPLE / 'experiment.yaml'), '--out', str(tmp_path / 'out'), '--no-diagnose',
             '--timeout', '240'], capture_output=True, text=True, timeout=300)
    finally:
        node.terminate()
        node.communicate(timeout=30)
    assert client.returncode == 0, client.stderr
    _check_report(json.loads(client.stdout), tmp_path / 'out')
    assert 'job 1: optimize' in client.stderr         # progress from /identification/status


def test_request_client_reports_the_node_error_in_one_line(tmp_path):
    node = _node()
    try:
        client = subprocess.run(
            [os.path.join(BIN, 'flex-ident'), 'request', '--bag', str(tmp_path / 'missing'),
             '--experiment', str(EXAMPLE / 'experiment.yaml'), '--timeout', '120', '--quiet'],
            capture_output=True, text=True, timeout=200)
    finally:
        node.terminate()
        node.communicate(timeout=30)
    assert client.returncode == 2
    lines = [line for line in client.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and 'does not exist' in lines[0], client.stderr


def test_request_client_without_a_node_says_so(tmp_path):
    client = subprocess.run(
        [os.path.join(BIN, 'flex-ident'), 'request', '--bag', 'b', '--experiment', 'e', '--quiet'],
        capture_output=True, text=True, timeout=60)
    assert client.returncode == 2 and 'no stiffness_identifier node' in client.stderr


def test_run_on_start_identifies_the_parameters(tmp_path):
    node = _node(f'bag:={EXAMPLE / "bag"}', f'experiment:={EXAMPLE / "experiment.yaml"}',
                 f'out:={tmp_path / "out"}', 'diagnose:=false', 'run_on_start:=true')
    try:
        import time
        end = time.monotonic() + 240
        while time.monotonic() < end and not (tmp_path / 'out' / 'report.json').exists():
            assert node.poll() is None, node.stderr.read()
            time.sleep(0.2)
        time.sleep(0.5)
    finally:
        node.terminate()
        node.communicate(timeout=30)
    report = json.loads((tmp_path / 'out' / 'report.json').read_text())
    _check_report(report, tmp_path / 'out')
