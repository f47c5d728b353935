"""The acceptance rehearsal's report and the shape-by-shape comparison of two of its methods
(``benchmarks/acceptance_rehearsal.py``, ``benchmarks/compare_rehearsal_methods.py``)."""
import json
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[4] / 'benchmarks'
sys.path.insert(0, str(BENCH))

from acceptance_rehearsal import summary_against_targets  # noqa: E402


def _run(shape, method, e=None, plan_rc=0, plan_cpu=3.0, sim_cpu=10.0):
    return {'shape': shape, 'rod': 'rod3', 'form': 'L_gb', 'method': method, 'dir': f'out/{shape}__{method}',
            'plan_rc': plan_rc, 'plan_cpu': plan_cpu, 'plan_wall': plan_cpu,
            **({} if e is None else {'sim_cpu': sim_cpu, 'sim_wall': sim_cpu, 'eval': {'e_mean_cm': e}})}


def test_targets_summary_with_numeric_runs_only():
    rows = [_run('a', 'numeric', 0.5), _run('a', 'numeric --shear least_force', 0.6)]
    out = summary_against_targets(rows, None)
    line = next(ln for ln in out if ln.startswith('| a |'))
    assert '| rod3 |' in line and '0.500' in line


def test_compare_rehearsal_methods(tmp_path):
    runs = [_run('a', 'numeric', 0.5), _run('a', 'numeric --shear least_force', 0.6, plan_cpu=20.0),
            _run('b', 'numeric', 0.3), _run('b', 'numeric --shear least_force', 0.2, plan_cpu=18.0),
            _run('c', 'numeric', plan_rc=2), _run('c', 'numeric --shear least_force', plan_rc=2)]
    (tmp_path / 'r.json').write_text(json.dumps({'runs': runs, 'load_end': 2.0}))
    out = tmp_path / 'cmp.md'
    subprocess.run([sys.executable, str(BENCH / 'compare_rehearsal_methods.py'), '--results', str(tmp_path / 'r.json'),
                    '--before', 'numeric', '--after', 'numeric --shear least_force', '--out', str(out)],
                   check=True, capture_output=True, cwd=BENCH)
    text = out.read_text()
    assert '| a | rod3 (L_gb) | 0.500 | 0.600 | +0.100 |' in text
    assert '| c | rod3 (L_gb) | - | - | - |' in text
    assert 'Shapes simulated by both: 2; mean e_mean 0.400 -> 0.400 cm' in text
    assert 'better by more than 0.005 cm: 1, worse: 1, within: 0' in text
    assert 'Median CPU of plan 3.0 -> 19.0 s' in text


def test_compare_rehearsal_methods_unknown_method(tmp_path):
    (tmp_path / 'r.json').write_text(json.dumps({'runs': [_run('a', 'numeric', 0.5)]}))
    p = subprocess.run([sys.executable, str(BENCH / 'compare_rehearsal_methods.py'), '--results',
                        str(tmp_path / 'r.json'), '--before', 'numeric', '--after', 'nn', '--out',
                        str(tmp_path / 'x.md')], capture_output=True, text=True, cwd=BENCH)
    assert p.returncode != 0 and "no runs of 'numeric' or of 'nn'" in p.stderr
    assert not (tmp_path / 'x.md').exists()
