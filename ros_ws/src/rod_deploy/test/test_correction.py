"""The deployment's closed loop (`rod-deploy correct`): effect selection on a cheap stand-in forward model, one
real simulated deployment with a wrong L_gb, a clean deployment, and the CLI's errors."""
import dataclasses
import json
from types import SimpleNamespace

import numpy as np
import pytest

from rod_deploy.cli.main import main as cli
from rod_deploy.deployment import correction, refinement
from rod_deploy.deployment.correction import CorrectionSettings, Deployment, correct, diagnose
from rod_deploy.deployment.metrics import eq17_error, write_deployed_csv
from rod_deploy.deployment.simulate import DeploymentError, SimulationSettings, simulate_deployment
from rod_deploy.planning.rod_description import load_rod_description, rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

ROD = rod_description_from_dict({'length': 0.3, 'radius': 0.002, 'L_gb': 0.034, 'friction': 0.5})
_a = np.linspace(0.0, 0.07 / 0.08, 30)
#: 5 cm straight, then 7 cm of an arc of radius 8 cm
PATTERN = np.vstack([np.column_stack([np.linspace(0, 0.05, 11)[:-1], np.zeros(10)]),
                     np.column_stack([0.05 + 0.08 * np.sin(_a), 0.08 * (1 - np.cos(_a))])])
FAST = SimulationSettings(edge_length_m=0.01, dt_s=0.1, max_gripper_speed_m_s=0.03, contact_tolerance_m=5e-4)


# ------------------------------------------------------------------- the statistics, on a stand-in forward model
def _stand_in(t, position, quaternion, rod, settings=None, progress=None):
    """A cheap, smooth, nonlinear stand-in for the simulator: the pattern led along itself in proportion to
    (L_gb - 3.4 cm), bent by the natural curvature, pulled back and shortened by too little friction."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(PATTERN, axis=0), axis=1))])
    lead = 0.4 * (rod.gravito_bending_length_m - 0.034)             # a stiffer rod leads along the pattern
    xy = np.column_stack([np.interp(s + lead, s, PATTERN[:, k]) for k in range(2)])
    k0 = rod.natural_curvature_per_m
    xy[:, 1] += 0.15 * k0 * s ** 2 * (1 + 0.3 * k0 * s)
    mu = rod.friction
    keep = s <= s[-1] * (1.0 - 0.2 * max(0.5 - mu, 0.0))
    xy = xy[keep]
    xy[:, 0] -= 0.15 * (0.5 - mu) * s[keep]
    return SimpleNamespace(deployed_xy=xy)


@pytest.fixture
def stand_in(monkeypatch):
    monkeypatch.setattr(refinement, 'simulate_deployment', _stand_in)
    return Deployment(np.zeros(2), np.zeros((2, 3)), np.tile([1.0, 0, 0, 0], (2, 1)), tuple(PATTERN[0]))


@pytest.mark.parametrize('truth, key, value', [
    ({'natural_curvature_per_m': 2.0}, 'natural_curvature_per_m', 2.0),
    ({'L_gb_m': 0.040}, 'L_gb_m', 0.040),
    ({'friction': 0.2}, 'friction', 0.2),
])
def test_the_effect_that_made_the_deployment_is_named_and_fitted(stand_in, truth, key, value):
    observed = _stand_in(None, None, None, correction.rod_with(ROD, truth)).deployed_xy
    observed = observed + np.random.default_rng(1).normal(0.0, 1e-4, observed.shape)   # perception-like noise
    d = diagnose(PATTERN, ROD, stand_in, observed, FAST)
    assert [e['key'] for e in d.effects_added] == [key], d.candidates
    assert d.fitted[key] == pytest.approx(value, rel=0.1)
    assert d.rms_after_m < 0.3 * d.rms_before_m
    e = d.effects_added[0]
    assert {'name', 'parameters', 'evidence', 'error_before', 'error_after'} <= set(e)


def test_a_perceived_shape_may_start_at_either_end(stand_in):
    observed = _stand_in(None, None, None, correction.rod_with(ROD, {'L_gb_m': 0.040})).deployed_xy
    a = diagnose(PATTERN, ROD, stand_in, observed, FAST)
    b = diagnose(PATTERN, ROD, stand_in, observed[::-1], FAST)
    assert [e['key'] for e in b.effects_added] == ['L_gb_m'] and b.fitted == pytest.approx(a.fitted)


def test_a_matching_deployment_adds_nothing_even_with_noise(stand_in):
    clean = _stand_in(None, None, None, ROD).deployed_xy
    for sigma in (0.0, 3e-4):
        observed = clean + np.random.default_rng(2).normal(0.0, sigma, clean.shape)
        d = diagnose(PATTERN, ROD, stand_in, observed, FAST)
        assert d.effects_added == [] and d.fitted == {}


def test_an_unexplained_residual_adds_nothing_and_says_so(stand_in):
    observed = _stand_in(None, None, None, ROD).deployed_xy.copy()
    observed[:, 1] += 0.004 * np.sin(40 * observed[:, 0])              # wiggles no candidate makes
    d = diagnose(PATTERN, ROD, stand_in, observed, FAST)
    assert d.effects_added == [] and d.fitted == {}
    assert len(d.warnings) == 1 and ('no candidate' in d.warnings[0] or 'nothing added' in d.warnings[0])


def _diagnosis_with_lgb(fitted_lgb, fitted_xy):
    rod = correction.rod_with(ROD, {'L_gb_m': fitted_lgb})
    effect = {'key': 'L_gb_m', 'parameters': {'L_gb_m': fitted_lgb, 'L_gb_m_declared': ROD.gravito_bending_length_m}}
    return correction.Diagnosis([effect], {'L_gb_m': fitted_lgb}, rod, fitted_xy, fitted_xy, fitted_xy, 0.0, 0.0)


@pytest.mark.parametrize('fragile', [True, False])
def test_a_replan_is_kept_only_if_rods_beside_the_fitted_one_lay_it_better_too(monkeypatch, fragile):
    """A stand-in simulator lays every trajectory on the pattern for the fitted rod exactly; rods 3 % off it lay it
    2 cm off when ``fragile`` (a replan near an instability), 1 mm off otherwise. The original trajectory is
    predicted 5 mm off."""
    fitted = 0.040

    def stand_in(t, position, quaternion, rod, settings=None, progress=None):
        off = 0.0 if rod.gravito_bending_length_m == fitted else (0.02 if fragile else 0.001)
        return SimpleNamespace(deployed_xy=PATTERN + [0.0, off])
    monkeypatch.setattr(refinement, 'simulate_deployment', stand_in)
    diag = _diagnosis_with_lgb(fitted, PATTERN + [0.0, 0.005])
    original = Deployment(np.zeros(2), np.zeros((2, 3)), np.tile([1.0, 0, 0, 0], (2, 1)), tuple(PATTERN[0]))
    rp = correction.replan(PATTERN, diag, original, PlannerSettings(), FAST)
    check = rp.robustness
    assert [r['value'] for r in check['neighbours']] == pytest.approx([fitted * 0.97, fitted * 1.03])
    assert rp.original_predicted_e_mean_cm == pytest.approx(0.5, abs=0.01)
    if fragile:
        assert not check['robust'] and check['worst_e_mean_cm'] == pytest.approx(2.0, abs=0.01)
        assert not rp.replanned and rp.t is original.t and rp.predicted_e_mean_cm == rp.original_predicted_e_mean_cm
    else:
        assert check['robust'] and check['worst_e_mean_cm'] == pytest.approx(0.1, abs=0.01)
        assert rp.replanned and rp.planner_L_gb_m == fitted and rp.predicted_e_mean_cm == pytest.approx(0.0)


def test_a_replan_whose_neighbour_fails_to_simulate_is_not_kept_and_the_report_says_why(monkeypatch):
    fitted = 0.040

    def stand_in(t, position, quaternion, rod, settings=None, progress=None):
        if rod.gravito_bending_length_m != fitted:
            raise DeploymentError('Newton did not converge')
        return SimpleNamespace(deployed_xy=PATTERN)
    monkeypatch.setattr(refinement, 'simulate_deployment', stand_in)
    diag = _diagnosis_with_lgb(fitted, PATTERN + [0.0, 0.005])
    monkeypatch.setattr(correction, 'diagnose', lambda *args, **kwargs: diag)
    original = Deployment(np.zeros(2), np.zeros((2, 3)), np.tile([1.0, 0, 0, 0], (2, 1)), tuple(PATTERN[0]))
    observed = PATTERN + [0.0, 0.005]
    report, _, rp = correct(PATTERN, ROD, observed, original, sim_settings=FAST)
    assert not rp.replanned and rp.robustness['worst_e_mean_cm'] is None
    assert all('Newton' in r['failed'] for r in rp.robustness['neighbours'])
    assert report['replan']['robustness']['robust'] is False
    assert report['error_after']['e_mean_cm'] == report['error_before']['e_mean_cm']
    assert any('a simulation failed' in w and 'original trajectory is kept' in w for w in report['warnings'])
    json.dumps(report, allow_nan=False)                 # the report stays strict JSON


# ----------------------------------------------------------------------------------- the real simulator
def test_a_rod_stiffer_than_declared_is_diagnosed_and_the_replan_is_never_worse():
    # Alg. 4's tangent start: with the friction-limited start (the planner's default), which bends the start by an
    # amount that depends on L_gb, the same wrong L_gb was measured to be fitted together with a spurious natural
    # curvature (forward selection added both; README "What does not work yet")
    # (and Alg. 4's curvature: with the curvature rate limit the replan for the fitted L_gb was chosen, predicted
    # 0.482 cm by the fitted rod against 0.472 observed; the report compares the two, README "What does not work")
    # (and Alg. 4's pattern, without the drag compensation's template: with it, the original plan's template moved by
    # 0.01 mm between the seventh round's drag model and bend_drag's shift term, and that alone turned the correction's
    # search to a replan (planner L_gb 0.025, no template under either model) that the fitted rod, L_gb 0.0459, predicts
    # at 0.46 cm and the true rod, 0.045, lays at 3.28 with its free end dragged 3 cm: a free-end instability this short
    # rod is near, not the correction's diagnosis, which this test checks; the twelfth round's check of rods beside
    # the fitted one does not catch it: simulated from the pattern's first point, as the correction does, rods 3 %
    # either side lay that replan at 0.55 / 0.60 cm and the true rod at 0.56; this observation is simulated from
    # below the hanging pose, 0.01 mm away, which lays it 3.8 cm off or fails to converge)
    tangent = PlannerSettings(start='tangent', max_kappa_bar_rate=np.inf, drag_compensation=False)
    true_rod = dataclasses.replace(ROD, gravito_bending_length_m=0.045)
    plan = plan_trajectory(PATTERN, ROD, tangent)
    observed = simulate_deployment(plan.t, plan.position, plan.quaternion, true_rod, FAST).deployed_xy
    report, diag, rp = correct(PATTERN, ROD, observed, Deployment(plan.t, plan.position, plan.quaternion,
                                                                  tuple(PATTERN[0])), planner_settings=tangent,
                               sim_settings=FAST, settings=CorrectionSettings(effects=('natural_curvature', 'L_gb')))
    assert [e['key'] for e in report['effects_added']] == ['L_gb_m'], report['candidates']
    assert report['parameters']['L_gb_m'] == pytest.approx(0.045, rel=0.15)
    # A replan is kept only where the fitted model predicts it lays the rod better. On this short rod, since the
    # planner's connective node moved to z = h (and the hanging pose to the stretched rod at rest), the plan for the
    # fitted L_gb is no longer predicted better, so the original is kept (measured: e_mean 0.477 cm both): check
    # that the kept or replanned trajectory, deployed with the TRUE rod, is never worse than the original.
    assert report['error_after']['e_mean_cm'] <= report['error_before']['e_mean_cm']
    after = simulate_deployment(rp.t, rp.position, rp.quaternion, true_rod, FAST).deployed_xy
    assert eq17_error(PATTERN, after)['e_mean_cm'] <= 1.02 * eq17_error(PATTERN, observed)['e_mean_cm']


def test_a_deployment_simulated_with_the_declared_rod_adds_nothing(tmp_path, capsys):
    plan = plan_trajectory(PATTERN, ROD)
    observed = simulate_deployment(plan.t, plan.position, plan.quaternion, ROD, FAST).deployed_xy
    report, diag, rp = correct(PATTERN, ROD, observed, None, sim_settings=FAST, replan_trajectory=True)
    assert report['effects_added'] == [] and rp is None
    assert report['error_after']['e_mean_cm'] == report['error_before']['e_mean_cm']
    assert report['simulations'] == 1                            # nothing beyond the noise floor to explain


# ------------------------------------------------------------------------------------------------ the CLI
def _files(tmp_path):
    np.savetxt(tmp_path / 'p.txt', PATTERN)
    (tmp_path / 'rod.yaml').write_text('length: 0.3\nradius: 0.002\nL_gb: 0.034\nfriction: 0.5\n')
    write_deployed_csv(tmp_path / 'd.csv', PATTERN)
    return {'p': tmp_path / 'p.txt', 'rod': tmp_path / 'rod.yaml', 'd': tmp_path / 'd.csv', 'out': tmp_path / 'out',
            'missing': tmp_path / 'nope.csv', 'bad': tmp_path / 'bad.csv'}


@pytest.mark.parametrize('extra, words', [
    (['--deployed', '{missing}'], 'cannot read deployed shape'),
    (['--deployed', '{bad}'], 'header'),
    (['--deployed', '{d}', '--effects', 'magnetism'], 'unknown effect(s) magnetism'),
    (['--deployed', '{d}', '--simulate'], 'give --replan too'),
    (['--deployed', '{d}', '--noise-floor-mm', '0'], '--noise-floor-mm must be positive'),
])
def test_cli_bad_input_is_one_error_line_and_writes_nothing(tmp_path, capsys, extra, words):
    f = _files(tmp_path)
    f['bad'].write_text('a,b\n1,2\n')
    args = ['correct', '--pattern', str(f['p']), '--rod', str(f['rod']), '--out', str(f['out'])]
    assert cli(args + [a.format(**f) for a in extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('rod-deploy correct: error: ') and words in err[0], err
    assert not f['out'].exists()


def test_cli_writes_the_report_and_the_plot(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(refinement, 'simulate_deployment', _stand_in)
    f = _files(tmp_path)
    observed = _stand_in(None, None, None, correction.rod_with(ROD, {'L_gb_m': 0.04})).deployed_xy
    write_deployed_csv(f['d'], observed)
    assert cli(['correct', '--pattern', str(f['p']), '--rod', str(f['rod']), '--deployed', str(f['d']),
                '--out', str(f['out']), '--replan', '--simulate', '--quiet']) == 0
    line = capsys.readouterr().out.strip().splitlines()
    assert len(line) == 1 and 'L_gb_m = 0.04' in line[0] and 'e_mean' in line[0]
    report = json.loads((f['out'] / 'report.json').read_text())
    assert [e['key'] for e in report['effects_added']] == ['L_gb_m']
    assert set(report) >= {'parameters', 'effects_added', 'warnings', 'error_before', 'error_after'}
    for name in ('correction.png', 'rod_fitted.yaml', 'traj_corrected.csv'):
        assert (f['out'] / name).exists()
    fitted = load_rod_description(f['out'] / 'rod_fitted.yaml')          # a rod file the planner takes
    assert fitted.gravito_bending_length_m == pytest.approx(0.04, rel=1e-3)


# ---------------------------------------------------------------- pre-compensation of a fitted natural curvature
LINE = np.column_stack([np.linspace(0.0, 0.15, 31), np.zeros(31)])


@pytest.mark.parametrize('k0', [3.0, -3.0])
def test_a_fitted_natural_curvature_is_precompensated_and_the_true_rod_lays_it_better(k0):
    """The planner does not model a natural curvature: the replan plans for a modified pattern with the fitted
    simulator in the loop. Here the fit is exact (the diagnosis given the true value), so what is checked is the
    pre-compensation itself: the corrected trajectory, deployed by the true rod, lies closer to the line (measured:
    e_mean 0.114 -> 0.040 cm for +3 /m, 0.148 -> 0.033 cm for -3 /m, 4 simulations each)."""
    true_rod = dataclasses.replace(ROD, natural_curvature_per_m=k0)
    plan = plan_trajectory(LINE, ROD)
    dep = Deployment(plan.t, plan.position, plan.quaternion, tuple(LINE[0]))
    observed = simulate_deployment(plan.t, plan.position, plan.quaternion, true_rod, FAST).deployed_xy
    diag = correction.Diagnosis(
        effects_added=[{'key': 'natural_curvature_per_m',
                        'parameters': {'natural_curvature_per_m': k0, 'natural_curvature_per_m_declared': 0.0}}],
        fitted={'natural_curvature_per_m': k0}, rod=true_rod, observed_xy=observed, nominal_xy=observed,
        fitted_xy=observed, rms_before_m=0.0, rms_after_m=0.0)
    rp = correction.replan(LINE, diag, dep, PlannerSettings(), FAST, simulate=True)
    assert rp.replanned and rp.precompensation is not None
    assert 1 <= rp.precompensation['simulations'] <= 4 and rp.robustness['robust']     # +-0.02 / L_gb lay it better too
    assert rp.simulations == rp.precompensation['simulations'] + rp.robustness['simulations'] == \
        rp.precompensation['simulations'] + 2
    e_before = eq17_error(LINE, observed, directed=True)['e_mean_cm']
    after = simulate_deployment(rp.t, rp.position, rp.quaternion, true_rod, FAST).deployed_xy
    e_after = eq17_error(LINE, after, directed=True)['e_mean_cm']
    assert rp.predicted_e_mean_cm == pytest.approx(e_after, abs=1e-3)      # the fitted model is the true one here
    assert e_after < 0.5 * e_before


def test_a_negative_natural_curvature_on_a_left_turn_is_named_with_its_sign():
    """The laid rod rolls ~80 degrees where the pattern turns against its natural curvature (README, the module doc):
    the response is not odd in the curvature's sign, so each sign has its own sensitivity. With the positive step
    alone this deployment was fitted as L_gb = 3.98 cm (measured)."""
    true_rod = dataclasses.replace(ROD, natural_curvature_per_m=-3.0)
    plan = plan_trajectory(PATTERN, ROD)
    observed = simulate_deployment(plan.t, plan.position, plan.quaternion, true_rod, FAST).deployed_xy
    d = diagnose(PATTERN, ROD, Deployment(plan.t, plan.position, plan.quaternion, tuple(PATTERN[0])), observed, FAST)
    assert [e['key'] for e in d.effects_added] == ['natural_curvature_per_m'], d.candidates
    assert d.fitted['natural_curvature_per_m'] == pytest.approx(-3.0, rel=0.1)
