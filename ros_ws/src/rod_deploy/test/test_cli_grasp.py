"""`rod-deploy grasp` command line (JSON contract of issue 4)."""
import argparse
import json

import pytest

from rod_deploy.cli import grasp as grasp_cli
from rod_deploy.cli.main import CliError


def _run(argv, capsys):
    parser = argparse.ArgumentParser(prog='rod-deploy')
    sub = parser.add_subparsers(dest='command', required=True)
    grasp_cli.register(sub)
    args = parser.parse_args(argv)
    rc = args.func(args)
    return rc, json.loads(capsys.readouterr().out)


def test_json_output_published_point(capsys):
    rc, out = _run(['grasp', '--ls', '13.68', '--kappa', '0', '--ks', '2087'], capsys)
    assert rc == 0
    assert set(out) == {'position', 'rotvec', 'force_residual', 'stable', 'time_s'}
    assert out['position'] == pytest.approx([2.5663, 0.0, 12.1824], abs=1e-3)
    assert out['rotvec'] == pytest.approx([0.0, -1.5708, 0.0], abs=1e-3)
    assert out['stable'] is True
    assert out['force_residual'] < 1e-8
    assert 0 < out['time_s'] < 5


def test_released_convention_and_methods(capsys):
    _, out = _run(['grasp', '--ls', '13.68', '--kappa', '0', '--ks', '2087', '--convention', 'released'], capsys)
    assert out['position'] == pytest.approx([2.5077, 0.0, 12.2409], rel=1e-3, abs=1e-6)
    _, a = _run(['grasp', '--ls', '7', '--kappa', '0.4', '--ks', '900', '--method', 'numeric',
                 '--no-stability'], capsys)
    _, b = _run(['grasp', '--ls', '7', '--kappa', '0.4', '--ks', '900', '--method', 'alg2', '--details'], capsys)
    assert a['stable'] is None
    assert b['position'] == pytest.approx(a['position'], abs=1e-6)
    assert b['inputs'] == {'ls_bar': 7.0, 'kappa_bar': 0.4, 'ks_bar': 900.0}
    assert a['position'][1] < 0


def test_inextensible_rod_accepts_inf(capsys):
    _, out = _run(['grasp', '--ls', '40', '--ks', 'inf', '--no-stability'], capsys)
    assert out['position'][0] == pytest.approx(2.5662, abs=5e-4)


@pytest.mark.parametrize('argv', [['--ls', '0', '--ks', '100'], ['--ls', '3', '--ks', '-1'],
                                  ['--ls', 'nan', '--ks', '100'], ['--ls', '3', '--ks', '100', '--kappa', 'inf']])
def test_user_errors_raise_cli_error(argv, capsys):
    parser = argparse.ArgumentParser(prog='rod-deploy')
    sub = parser.add_subparsers(dest='command', required=True)
    grasp_cli.register(sub)
    args = parser.parse_args(['grasp', *argv])
    with pytest.raises(CliError):
        args.func(args)


def test_through_main_exit_code(capsys, monkeypatch):
    from rod_deploy.cli import main as cli_main
    monkeypatch.setattr(cli_main, 'SUBCOMMAND_MODULES', ('grasp',))   # other subcommands live elsewhere
    assert cli_main.main(['grasp', '--ls', '-2', '--ks', '100']) == 2
    assert 'error' in capsys.readouterr().err
    assert cli_main.main(['grasp', '--ls', '5', '--ks', '100', '--no-stability']) == 0
    assert json.loads(capsys.readouterr().out)['position'][2] > 0


def test_run_as_a_module_gives_the_one_line_error(tmp_path):
    """`python -m rod_deploy.cli.main` loads main.py twice (as __main__ and as the package module): a subcommand's
    CliError must still be caught (one line, exit 2, no traceback)."""
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, '-m', 'rod_deploy.cli.main', 'evaluate', '--pattern',
                           str(tmp_path / 'missing.csv'), '--deployed', str(tmp_path / 'missing2.csv')],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert 'Traceback' not in proc.stderr
    assert proc.stderr.startswith('rod-deploy evaluate: error: ') and 'does not exist' in proc.stderr
