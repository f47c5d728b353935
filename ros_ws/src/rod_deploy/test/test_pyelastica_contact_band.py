"""The PyElastica replay's table (``benchmarks/pyelastica_replay.py``): a rod that does not touch the table gets no
force from it, neither a normal force nor friction. With PyElastica's own contact band (an element counts as touching
while its centreline is within 0.1 mm above the contact height) a rod 50 um above the table was carried and braked
as if lying on it: the laid rod floated on that band and the descending rod was gripped up to an element before its
touch-down point (``benchmarks/results/simulator_gap_r9.md``).

PyElastica lives in the benchmark-only ``.venv-bench`` (``make bench-env``); the check runs there in a subprocess
and is skipped when that environment is absent."""
import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[4]
BENCH_PY = ROOT / '.venv-bench' / 'bin' / 'python'

SCRIPT = """
import json
from pyelastica_replay import table_force_on_level_rod
print(json.dumps({str(g): table_force_on_level_rod(g) for g in (5e-5, 1e-5, -2e-6)}))
"""


@pytest.fixture(scope='module')
def forces():
    if not BENCH_PY.exists():
        pytest.skip('.venv-bench (PyElastica) not built: make bench-env')
    env = dict(os.environ, PYTHONPATH=f"{ROOT / 'ros_ws/src/rod_deploy'}{os.pathsep}{ROOT / 'benchmarks'}")
    out = subprocess.run([str(BENCH_PY), '-c', SCRIPT], env=env, cwd=ROOT, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    return {float(k): v for k, v in json.loads(out.stdout.strip().splitlines()[-1]).items()}


@pytest.mark.parametrize('gap_m', [5e-5, 1e-5])
def test_a_rod_above_the_table_gets_no_force_from_it(forces, gap_m):
    normal, friction = forces[gap_m]
    assert normal == 0.0 and friction == 0.0


def test_a_rod_pressed_into_the_table_is_carried_and_braked(forces):
    normal, friction = forces[-2e-6]
    weight = 1180.0 * 3.141592653589793 * 0.002 ** 2 * 0.02 * 9.81
    assert normal > weight                      # its weight and the penalty spring's push
    assert 0.0 < friction <= 0.5 * normal + 1e-12
