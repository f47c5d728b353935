"""Rod files of the acceptance (issue #10) through the command line, written by hand: a nonsense or ambiguous
file (a boolean, a key given twice, two stiffness forms, values in millimetres) gives one error line naming the field,
exit 2, no traceback and no trajectory (found by the acceptance rehearsal, ``benchmarks/acceptance_rehearsal.py``)."""
import re

import numpy as np
import pytest

from rod_deploy.cli.main import main
from rod_deploy.planning.rod_description import RodDescriptionError, load_rod_description, rod_description_from_dict

ROD3 = 'length: 0.89\nradius: 0.002\nL_gb: 0.034\nfriction: 0.5\n'
ARC = np.column_stack([0.1 * np.sin(np.linspace(0, 1.5, 60)), 0.1 * (1 - np.cos(np.linspace(0, 1.5, 60)))])


def _lines(xy, fmt='{x:.6f} {y:.6f}'):
    return ''.join(fmt.format(x=x, y=y) + '\n' for x, y in xy)


def _plan(tmp_path, capsys, pattern_text, rod_text=ROD3, method='nn'):
    (tmp_path / 'p.txt').write_text(pattern_text)
    (tmp_path / 'rod.yaml').write_text(rod_text)
    out = tmp_path / 'traj.csv'
    rc = main(['plan', '--pattern', str(tmp_path / 'p.txt'), '--rod', str(tmp_path / 'rod.yaml'), '--method', method,
               '--out', str(out)])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    return rc, err, out.exists()


@pytest.mark.parametrize('rod, words', [
    ('length: 0.89\nradius: 0.002\nL_gb: 0.034\nfriction: yes\n', '"friction" must be a number'),   # was mu = 1
    ('length: true\nradius: 0.002\nL_gb: 0.034\n', '"length" must be a number'),
    ('length: 0.89\nradius: 0.002\nL_gb: 0.034\nL_gb: 0.05\n', r'"L_gb" is given twice \(line 4\)'),  # was 0.05
    ('length: 0.89\nradius: 0.002\nL_gb: 0.034\nloop_height: 0.05\n', 'both L_gb and loop_height'),   # was L_gb
    ('length: 0.89\nradius: 0.002\nloop_height: 0.03\nyoungs_modulus: 1e6\ndensity: 1180\n',
     'both loop_height and youngs_modulus'),
    ('length: 0.89\nradius: 0.002\nyoungs_modulus: 1e6\n', 'youngs_modulus needs density'),
    # values in millimetres: were planned by the intuitive method (a 2 m thick rod; an 890 m rod hanging 890 m up)
    ('length: 0.89\nradius: 2\nL_gb: 0.034\n', 'radius 2 m is not smaller than L_gb'),
    ('length: 890\nradius: 2\nL_gb: 34\n', 'length 890 m is longer than 20 m'),
    ('length: [0.89\nradius: 0.002\n', 'not valid YAML'),                                           # one line
])
def test_nonsense_rod_files_are_refused_in_one_line(tmp_path, capsys, rod, words):
    rc, err, written = _plan(tmp_path, capsys, _lines(ARC), rod, method='intuitive')
    assert rc == 2 and len(err) == 1 and not written, err
    assert words in err[0] or re.search(words, err[0]), err[0]
    (tmp_path / 'r.yaml').write_text(rod)
    with pytest.raises(RodDescriptionError):
        load_rod_description(tmp_path / 'r.yaml')


def test_density_beside_l_gb_stays_allowed():
    """``rod-deploy correct`` writes rod_fitted.yaml with L_gb and the density (the simulator's mass)."""
    rod = rod_description_from_dict({'length': 0.89, 'radius': 0.002, 'L_gb': 0.034, 'density': 1180.0})
    assert rod.gravito_bending_length_m == 0.034 and rod.density_kg_m3 == 1180.0


def test_the_three_forms_of_a_rod_file_give_the_same_trajectory(tmp_path, capsys):
    lgb, h, rho = 0.034, 0.002, 1180.0
    forms = {'L_gb': f'L_gb: {lgb!r}', 'loop': f'loop_height: {0.9066 * lgb!r}',
             'E': f'youngs_modulus: {8 * rho * 9.81 * lgb ** 3 / h ** 2!r}\ndensity: {rho}'}
    trajs = {}
    for k, v in forms.items():
        rc, err, written = _plan(tmp_path, capsys, _lines(ARC), f'length: 0.89\nradius: {h}\n{v}\n')
        assert rc == 0 and written
        trajs[k] = np.loadtxt(tmp_path / 'traj.csv', delimiter=',', skiprows=1)
    assert np.allclose(trajs['L_gb'], trajs['loop'], atol=1e-6) and np.allclose(trajs['L_gb'], trajs['E'], atol=1e-6)


