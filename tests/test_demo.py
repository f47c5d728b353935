"""`make demo`'s script end to end in quick mode (the 6-link example, a coarse rod simulation): both flows run as
nodes in one process and out/ gets what the README announces."""
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_demo_runs_both_graphs_and_writes_out(tmp_path):
    out = tmp_path / 'out'
    out.mkdir()
    (out / 'stale.txt').write_text('from an earlier run')
    proc = subprocess.run([sys.executable, str(ROOT / 'scripts' / 'demo.py'), '--out', str(out), '--quick'],
                          capture_output=True, text=True, timeout=900, env=dict(os.environ))
    assert proc.returncode == 0, proc.stderr[-3000:]
    for k in (1, 2, 3):
        assert f'=== {k}.' in proc.stdout
    assert '=== summary' in proc.stdout and not (out / 'stale.txt').exists()      # out/ is overwritten
    report = json.loads((out / 'report.json').read_text())
    assert abs(report['parameters']['k_theta'] - 5.0) < 0.05 and abs(report['parameters']['k_phi'] - 3.0) < 0.03
    assert report['effects_added'] == []                 # the closed loop ran and invented nothing on clean data
    deployment = json.loads((out / 'deployment.json').read_text())
    assert deployment['e_mean_cm'] < 3.0 and 0.7 < deployment['coverage'] < 1.3, deployment
    assert deployment['tracking']['executed_vs_planned_max_mm'] < 5.0
    assert set(deployment['timings_s']) >= {'perception', 'planning', 'rod_simulation', 'total'}
    for name in ('cost_vs_iteration.png', 'end_effector_path.png', 'residual_over_time.png', 'deployment.png',
                 'perception_overlay.png'):
        assert (out / name).stat().st_size > 1000, name
    from robot_bridge.bagio.raw import topic_types
    recorded = topic_types(out / 'recording')
    assert list((out / 'recording').glob('*.mcap'))
    assert {'/joint_states', '/deploy_request', '/gripper_trajectory', '/arm_controller/joint_trajectory',
            '/deploy_result', '/deployed_shape', '/deploy_markers', '/identification/result',
            '/identification/markers'} <= set(recorded)
