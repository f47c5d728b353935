"""Simulation-in-the-loop refinement (`rod-deploy plan --refine N`, `deployment/refinement.py`): the iteration on a
stand-in, the normal offsets, a real short deployment whose predicted error must drop, and the CLI."""
import json
from types import SimpleNamespace

import numpy as np
import pytest

from rod_deploy.cli.main import main as cli
from rod_deploy.deployment import refinement
from rod_deploy.deployment.metrics import eq17_error
from rod_deploy.deployment.refinement import (Candidate, Deployment, RefinementSettings, _normal_offsets, refine,
                                              refine_plan)
from rod_deploy.deployment.simulate import DeploymentError, SimulationSettings
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory
from rod_deploy.planning.trajectory_io import read_trajectory_csv

ROD = rod_description_from_dict({'length': 0.3, 'radius': 0.002, 'L_gb': 0.034, 'friction': 0.5})
LINE = np.column_stack([np.linspace(0.0, 0.15, 31), np.zeros(31)])
FAST = SimulationSettings(edge_length_m=0.01, dt_s=0.1, max_gripper_speed_m_s=0.03, contact_tolerance_m=5e-4)
#: 10 cm straight, a left turn of 90 degrees on a radius of 5 cm, 3 cm straight (a rounded corner; the lead is long
#: enough for friction 0.5 to hold the bend's moment: a 4 cm lead into a 3 cm radius is refused by the planner)
_a = np.linspace(0.0, 0.5 * np.pi, 25)[1:]
CORNER = np.vstack([np.column_stack([np.linspace(0.0, 0.10, 21), np.zeros(21)]),
                    np.column_stack([0.10 + 0.05 * np.sin(_a), 0.05 * (1 - np.cos(_a))]),
                    np.column_stack([np.full(6, 0.15), 0.05 + np.linspace(0.0, 0.03, 7)[1:]])])


def _stand_in_planner(points, rod, settings):
    """The planner as a stand-in: the gripper follows the template it is given, in the table's plane."""
    p = np.asarray(points, float)
    return SimpleNamespace(t=np.arange(len(p), dtype=float), position=np.column_stack([p, np.zeros(len(p))]),
                           quaternion=np.tile([1.0, 0, 0, 0], (len(p), 1)))


@pytest.mark.parametrize('offset', ['arc_length', 'normal'])
def test_refinement_converges_on_a_stand_in_and_survives_a_failed_simulation(monkeypatch, offset):
    """Stand-in: the rod lies exactly on the template, shifted sideways by a smooth bias (what the planner does not
    model); the loop must move the template against the bias, keep the best, and treat a failed simulation (the
    second one here) as a worse template, not abort."""
    bias = lambda xy: np.column_stack([np.zeros(len(xy)), 0.004 * np.sin(20.0 * xy[:, 0])])  # noqa: E731
    calls = {'n': 0}

    def lay(t, position, quaternion, rod, settings=None, progress=None):
        calls['n'] += 1
        if calls['n'] == 2:
            raise DeploymentError('diverged (stand-in)')
        return SimpleNamespace(deployed_xy=position[:, :2] + bias(position[:, :2]))

    monkeypatch.setattr(refinement, 'plan_trajectory', _stand_in_planner)
    monkeypatch.setattr(refinement, 'simulate_deployment', lay)
    first = _stand_in_planner(LINE, ROD, None)
    d0 = LINE + bias(LINE)
    e0 = eq17_error(LINE, d0, directed=True)['e_mean_cm']
    start = Candidate(e0, Deployment(first.t, first.position, first.quaternion, tuple(LINE[0])), d0)
    best, n, record = refine(LINE, ROD, ROD, start, PlannerSettings(), FAST, RefinementSettings(offset=offset))
    assert n == 4 and len(record['iterations']) == 4
    assert record['iterations'][1]['accepted'] is False and 'diverged' in record['iterations'][1]['note']
    assert best.replanned and best.e_mean_cm < 0.3 * e0
    assert record['predicted_e_mean_cm'] == best.e_mean_cm and record['start_predicted_e_mean_cm'] == e0


def test_nothing_better_keeps_the_start(monkeypatch):
    """A simulator that lays every template worse than the start: the start is returned, the gain halves until it
    is below min_gain (1, 0.5, 0.25: three simulations)."""
    monkeypatch.setattr(refinement, 'plan_trajectory', _stand_in_planner)
    monkeypatch.setattr(refinement, 'simulate_deployment', lambda t, p, q, rod, s=None, cb=None: SimpleNamespace(
        deployed_xy=p[:, :2] + [0.0, 0.01]))
    first = _stand_in_planner(LINE, ROD, None)
    start = Candidate(0.01, Deployment(first.t, first.position, first.quaternion, (0.0, 0.0)), LINE.copy())
    best, n, record = refine(LINE, ROD, ROD, start, PlannerSettings(), FAST, RefinementSettings(simulations=10))
    assert best is start and n == 3 and [h['gain'] for h in record['iterations']] == [1.0, 0.5, 0.25]


def test_normal_offsets_ignore_a_lag_along_the_curve():
    """D = P shifted 5 mm along itself and 2 mm to the left: the normal offsets move T 2 mm to the right only."""
    P = np.column_stack([np.linspace(0.0, 0.2, 41), np.zeros(41)])
    D = np.column_stack([np.linspace(-0.1, 0.3, 81) + 0.005, np.full(81, 0.002)])
    step = _normal_offsets(P, D)
    assert step[:, 0] == pytest.approx(0.0, abs=1e-12)
    assert step[:, 1] == pytest.approx(-0.002, abs=1e-12)


@pytest.mark.parametrize('bad', [dict(simulations=0), dict(simulations=2.5), dict(gain=0.0), dict(min_gain=2.0),
                                 dict(smoothing_m=-0.01), dict(offset='sideways')])
def test_bad_settings_are_refused(bad):
    with pytest.raises(ValueError):
        RefinementSettings(**bad).validate()


# ----------------------------------------------------------------------------------- the real simulator
def test_refinement_lowers_the_predicted_error_of_a_corner():
    """A 0.3 m rod laid around a rounded corner in our DER: the refined plan is predicted to lie closer to the
    pattern than the unrefined one (the prediction re-simulated from the written trajectory)."""
    planner = PlannerSettings()
    plan = plan_trajectory(CORNER, ROD, planner)
    best, record = refine_plan(CORNER, ROD, plan, planner, FAST, RefinementSettings(simulations=3))
    assert 2 <= record['simulations'] <= 4
    assert best.replanned and best.e_mean_cm < 0.8 * record['start_predicted_e_mean_cm'], record
    dep = best.deployment
    again = refinement.ForwardModel(dep, FAST).deployed(ROD)
    assert eq17_error(CORNER, again, directed=True)['e_mean_cm'] == pytest.approx(best.e_mean_cm, abs=1e-6)


# ------------------------------------------------------------------------------------------------ the CLI
def _files(tmp_path):
    np.savetxt(tmp_path / 'p.txt', CORNER)
    (tmp_path / 'rod.yaml').write_text('length: 0.3\nradius: 0.002\nL_gb: 0.034\nfriction: 0.5\n')
    return tmp_path / 'p.txt', tmp_path / 'rod.yaml', tmp_path / 'traj.csv'


@pytest.mark.parametrize('n, words', [('1', 'N must be at least 2, got 1'), ('0', 'N must be at least 2, got 0'),
                                      ('-3', 'N must be at least 2, got -3')])
def test_cli_bad_refine_is_one_error_line_and_writes_nothing(tmp_path, capsys, n, words):
    p, rod, out = _files(tmp_path)
    assert cli(['plan', '--pattern', str(p), '--rod', str(rod), '--out', str(out), '--refine', n]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('rod-deploy plan: error: ') and words in err[0], err
    assert not out.exists()


def test_cli_refine_not_an_integer_is_refused(tmp_path, capsys):
    p, rod, out = _files(tmp_path)
    with pytest.raises(SystemExit) as e:
        cli(['plan', '--pattern', str(p), '--rod', str(rod), '--out', str(out), '--refine', 'three'])
    assert e.value.code == 2 and "invalid int value: 'three'" in capsys.readouterr().err
    assert not out.exists()


def test_cli_refined_plan_writes_the_contract_csv_and_reports_before_and_after(tmp_path, capsys, monkeypatch):
    """`rod-deploy plan --refine 3` on the corner (the library's simulation settings made coarse here for speed):
    the JSON line's refine record, a trajectory CSV in the contract's format that starts at the hanging pose
    (above the free end, which stays at the pattern's first point)."""
    monkeypatch.setattr(refinement, 'SimulationSettings', lambda: FAST)
    p, rod, out = _files(tmp_path)
    assert cli(['plan', '--pattern', str(p), '--rod', str(rod), '--out', str(out), '--refine', '3', '--quiet',
                '--plot', str(tmp_path / 'plan.png')]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    r = summary['refine']
    assert 2 <= r['simulations'] <= 3 and r['friction'] == 0.5
    assert r['predicted_e_mean_cm_after'] <= r['predicted_e_mean_cm_before']
    assert r['refined'] == (r['predicted_e_mean_cm_after'] < r['predicted_e_mean_cm_before'])
    assert out.read_text().splitlines()[0] == 't,x,y,z,qx,qy,qz,qw'
    t, pos, q = read_trajectory_csv(out)
    assert len(t) == summary['poses'] and np.all(np.diff(t) > 0)
    assert pos[0, :2] == pytest.approx(CORNER[0], abs=1e-3) and (tmp_path / 'plan.png').exists()
