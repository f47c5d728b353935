"""`make demo`'s script end to end (quick mode: the deployments are planned, not simulated): every step runs and
writes what it announces."""
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_demo_script_runs_every_step(tmp_path):
    out = tmp_path / 'demo'
    proc = subprocess.run([sys.executable, str(ROOT / 'scripts' / 'demo.py'), '--out', str(out), '--quick'],
                          capture_output=True, text=True, timeout=600, env=dict(os.environ))
    assert proc.returncode == 0, proc.stderr[-2000:]
    for k in range(1, 8):
        assert f'=== {k}.' in proc.stdout
    assert '2000 of 2000 messages recorded, byte-identical: yes' in proc.stdout
    report = json.loads((out / 'identification' / 'report.json').read_text())
    assert abs(report['parameters']['k_theta'] - 5.0) < 0.025 and abs(report['parameters']['k_phi'] - 3.0) < 0.015
    diagnosis = json.loads((out / 'diagnosis' / 'report.json').read_text())
    assert [e['name'] for e in diagnosis['effects_added']] == ['loop joint viscous damping']
    for name in ('overlay.png', 'path.csv', 'pattern.txt', 'traj_nn.csv', 'traj_intuitive.csv', 'plan_nn.png'):
        assert (out / name).exists(), name
    assert (out / 'traj_nn.csv').read_text().startswith('t,x,y,z,qx,qy,qz,qw\n')
