"""Identification from a recorded bag and an experiment YAML: the whole job behind ``flex-ident identify`` and the
``stiffness_identifier`` node.

Stages (reported through ``progress`` as dicts with 'stage' and 'fraction', plus 'iteration' and 'cost' while
optimizing):

1. ``load``: experiment (validated), model (URDF arm + contract loop), bag (contract reader, window, uniform grid);
2. ``equilibrium``: the object's static equilibrium at the first measured arm angles (recordings start at rest);
3. ``feedback``: the LQR gains of the stabilizing feedback (fixed from here on) and the VI substeps;
4. ``optimize``: the optimizer on the paper's cost (end-effector error) or the joint-angle variant;
5. ``report``: parameter standard deviations from the curvature at the optimum, errors before/after,
   ``report.json`` (CONTRACTS.md section 3) and the plots.

Bad input raises a ValueError subclass with one clear message and writes nothing; a stale report.json in the output
directory is removed first so that no old result is mistaken for this run's.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..mechanics.assembly import build_model
from ..mechanics.experiment import load_experiment
from ..mechanics.static_equilibrium import EquilibriumError, static_equilibrium
from ..mechanics.variational_integrator import stable_substeps
from .feedback import FeedbackWeights, lqr_tracking_feedback
from .measurement import load_measurements
from .optimizers import RESCUE_COST_FRACTION, canonical_method, optimize
from .problem import IdentificationProblem
from .report import build_report, write_report

Progress = Callable[[dict], None]


class IdentificationInputError(ValueError):
    """Input that makes identification impossible (named in the message)."""


@dataclass
class IdentificationSettings:
    method: str = 'lm'
    cost: str | None = None                     # None: the experiment's (default end_effector)
    max_iterations: int | None = None           # None: the experiment's (lm) or the method's default
    feedback: FeedbackWeights = FeedbackWeights()
    torque_hold: str = 'midpoint'               # effort over [t_k, t_{k+1}]: 'midpoint' average or 'zoh' (tau_k)
    plots: bool = True
    continuation: bool = True                   # warm start on the first 2.5 s, 5 s, 10 s, ... of the recording
    first_window_s: float = 2.5
    diagnose: bool = True                       # closed loop: find, add and jointly identify missing effects
    validation_fraction: float = 0.3            # arm-only experiments: last part of the window, never fitted


@dataclass
class IdentificationRun:
    """Everything a caller may want beyond the report (used by benchmarks and the next issue's diagnosis)."""
    report: dict
    model: object
    problem: IdentificationProblem
    result: object
    initial: object                             # Evaluation at the initial parameters


def _notify(progress: Progress | None, **info):
    if progress is not None:
        progress(info)


def prepare(bag_path, experiment_path, settings: IdentificationSettings, progress: Progress | None = None):
    """Load and validate everything, build the problem (stages load, equilibrium, feedback)."""
    _notify(progress, stage='load', fraction=0.0)
    experiment = load_experiment(experiment_path)
    specs = experiment.identify.parameters
    model = build_model(experiment)
    if not specs:
        raise IdentificationInputError(
            f'{experiment.path}: identify.parameters is empty, nothing to identify (parameters of this model: '
            f'{", ".join(model.coef_names)})')
    bag = Path(bag_path)
    if not bag.exists():
        raise IdentificationInputError(f'bag {bag_path} does not exist')
    joints = [model.coord_names[i] for i in model.measured_coords]
    data, notes = load_measurements(bag, joints, experiment.identify.window_s)
    _notify(progress, stage='equilibrium', fraction=0.0)
    coef0 = model.coef_values()
    q_guess = np.zeros(model.n)
    q_guess[model.measured_coords] = data.theta[0]
    try:
        eq0 = static_equilibrium(model, coef0, q_guess)
    except EquilibriumError as exc:
        raise IdentificationInputError(f'{exc} (experiment {experiment.path}, first sample of bag {bag_path})') \
            from None
    _notify(progress, stage='feedback', fraction=0.0)
    substeps = stable_substeps(model, coef0, data.dt, eq0.q, eq0.mu)
    feedback = lqr_tracking_feedback(model, coef0, eq0.q, data.dt, settings.feedback, horizon_steps=len(data.t_s))
    cost_kind = settings.cost or experiment.identify.cost
    problem = IdentificationProblem(model, data, [p.name for p in specs], [p.min for p in specs],
                                    [p.max for p in specs], feedback, substeps=substeps, cost_kind=cost_kind,
                                    torque_hold=settings.torque_hold)
    notes.update({'initial_equilibrium_iterations': eq0.newton_iterations, 'substeps_initial': substeps})
    return experiment, model, problem, notes


def identify(bag_path, experiment_path, out_dir, settings: IdentificationSettings | None = None,
             progress: Progress | None = None) -> IdentificationRun:
    """Run the identification and write ``out_dir/report.json`` and plots; returns the run."""
    t_start = time.monotonic()
    settings = settings or IdentificationSettings()
    method = canonical_method(settings.method)
    out = Path(out_dir)
    stale = out / 'report.json'
    if stale.exists():
        stale.unlink()
    spec = load_experiment(experiment_path)
    if spec.object is None:                     # an arm alone: the closed loop in the torque domain
        from .arm_only import identify_arm_only
        report = identify_arm_only(bag_path, spec, out, settings.validation_fraction, settings.plots, progress)
        return IdentificationRun(report=report, model=None, problem=None, result=None, initial=None)
    experiment, model, problem, notes = prepare(bag_path, experiment_path, settings, progress)
    if settings.diagnose:
        from ..diagnosis.closed_loop import validation_split
        try:
            validation_split(problem, settings.validation_fraction)
        except ValueError as exc:
            raise IdentificationInputError(f'{exc} (--validation-fraction)') from None
    specs = experiment.identify.parameters
    p0 = np.array([p.initial for p in specs], float)
    max_iterations = settings.max_iterations or (experiment.identify.max_iterations if method == 'lm' else None)

    windows = warm_start_windows(problem.data, settings.first_window_s) if settings.continuation else []
    initial, stages, start, rescue_above = None, [], p0, 'auto'
    if windows:
        # the error before is that of the whole recording at the initial guess, whatever the warm start does
        initial = problem.evaluate(p0, jacobian=False)
        if not initial.ok:
            raise IdentificationInputError(f'the model cannot be simulated at the initial parameters: '
                                           f'{initial.failure} (bag {bag_path}, experiment {experiment.path})')
        rescue_above = RESCUE_COST_FRACTION * initial.cost
    offset = 0
    evaluations = {0: initial} if initial is not None else {}

    def on_iteration(info):
        iteration = info['iteration'] + offset
        evaluations[iteration] = info.pop('evaluation')
        _notify(progress, stage='optimize', iteration=iteration, cost=info['cost'],
                fraction=info['fraction'], parameters=dict(zip(problem.free, info['params'])))

    try:
        if windows:
            start, stages = warm_start(problem, p0, method, windows, progress)
            offset = sum(stage['iterations'] for stage in stages)
        _notify(progress, stage='optimize', iteration=offset, fraction=0.0)
        result = optimize(problem, start, method, max_iterations, on_iteration, rescue_above=rescue_above)
    except RuntimeError as exc:
        raise IdentificationInputError(f'{exc} (bag {bag_path}, experiment {experiment.path})') from None
    if initial is None:
        initial = evaluations[0]
    if stages:
        for entry in result.history:
            entry['iteration'] += offset
        result.history.insert(0, {'iteration': 0, 'cost': float(initial.cost), 'params': [float(v) for v in p0],
                                  'evaluations': 1})
        result.iterations += offset
        result.evaluations += 1 + sum(stage['simulations'] for stage in stages)
        notes['continuation'] = stages
    _notify(progress, stage='report', fraction=0.0)
    report = build_report(problem, result, initial, experiment, bag_path, method, notes,
                          wall_time_s=time.monotonic() - t_start)
    if settings.diagnose:
        add_diagnosis(report, problem, result, progress, initial, settings.validation_fraction)
    plots = []
    if settings.plots:
        from .plots import write_plots
        out.mkdir(parents=True, exist_ok=True)
        plots = write_plots(out, problem, result, initial, evaluations, stages)
    report['plots'] = [p.name for p in plots]
    report['wall_time_s'] = time.monotonic() - t_start
    write_report(out, report)
    _notify(progress, stage='done', fraction=1.0)
    return IdentificationRun(report=report, model=model, problem=problem, result=result, initial=initial)


def add_diagnosis(report: dict, problem, result, progress: Progress | None = None, initial=None,
                  validation_fraction: float | None = 0.3):
    """The closed loop (``flex_ident.diagnosis``): effects_added, and the declared parameters and overall error
    after the last added effect (the declared-only fit is kept under 'declared_only').

    validation_fraction: the last part of the window held out; every model along the way is refitted on the rest
    and its error on the held-out part goes under 'validation' in error_before / error_after (the overall ones and
    each effect's; error_before's is the initial guess simulated over the whole window, nothing fitted)."""
    from ..diagnosis.closed_loop import add_validation, diagnose, measured_noise_level, structure_warning

    _notify(progress, stage='diagnose', fraction=0.0)
    t0 = time.monotonic()
    found = diagnose(problem, result.params, progress)
    report['effects_added'] = found['effects_added']
    report['diagnosis'] = {'rounds': found['rounds'], 'wall_time_s': found['wall_time_s'],
                           'all_parameters': found['parameters'], 'cost': found['cost'],
                           'declared_refit_on_diagnosis_cost': found['declared_refit']}
    declared_error = report['error_after']
    if found['effects_added']:
        report['declared_only'] = {'parameters': report['parameters'], 'parameter_std': report['parameter_std'],
                                   'error_after': declared_error}
        last = found['effects_added'][-1]
        report['parameters'] = dict(last['declared_parameters_after'])
        report['parameter_std'] = {n: last['declared_parameter_std'].get(n) for n in problem.free}
        report['error_after'] = found['error_after']
    if validation_fraction is not None:
        validation = add_validation(found, problem, validation_fraction, found['_effects'],
                                    dict(zip(problem.free, (float(v) for v in result.params))), progress)
        declared_error['validation'] = validation['declared']
        report['error_after']['validation'] = validation['final']
        if initial is not None and initial.ok:
            n_fit = validation['fitted_samples']
            report['error_before']['validation'] = problem.cost.errors(initial.traj.q, slice(n_fit, None))
        report['diagnosis']['validation'] = {k: validation[k] for k in ('fraction', 'from_s', 'fitted_samples')}
    noise = measured_noise_level(problem)
    report['diagnosis']['measured_noise'] = noise
    warning = structure_warning(report['error_after'], noise, found['effects_added'])
    report['diagnosis']['model_structure_ok'] = warning is None
    if warning:
        report.setdefault('warnings', []).append(warning)
    report['diagnosis']['wall_time_s'] = time.monotonic() - t0


def warm_start_windows(data, first_window_s=2.5) -> list[float]:
    """The warm start's windows [s]: 2.5, 5, 10, ... while shorter than 3/4 of the recording."""
    duration = float(data.t_s[-1] - data.t_s[0])
    windows, window = [], float(first_window_s)
    while 0 < window < 0.75 * duration:
        windows.append(window)
        window *= 2
    return windows


def warm_start(problem, p0, method, windows, progress: Progress | None = None):
    """Horizon continuation: identify on the first ``windows`` seconds of the recording in turn (see
    :func:`warm_start_windows`), each stage starting from the last one's result; returns (parameters, stages).

    Far from the truth a soft loop driven through a long, wide motion moves chaotically: the cost of the whole
    recording has many local minima and its sensitivities explode, while the cost of a short window is smooth. Each
    doubling keeps the start inside the basin of the true parameters."""
    data = problem.data
    duration = float(data.t_s[-1] - data.t_s[0])
    stages, params = [], np.asarray(p0, float)
    for window in windows:
        short = problem.truncated(int(round(window / data.dt)) + 1)
        _notify(progress, stage='warm start', window_s=window, fraction=window / duration)
        result = optimize(short, params, method, None, None, rescue_above='auto' if not stages else None)
        params = result.params
        stages.append({'window_s': window, 'iterations': int(result.iterations), 'simulations': int(result.evaluations),
                       'parameters': dict(zip(problem.free, (float(v) for v in params))),
                       'cost': float(result.evaluation.cost), 'message': result.message,
                       'cost_history': [float(h['cost']) for h in result.history]})
        problem.substeps = max(problem.substeps, short.substeps)
    return params, stages


def run_identification(bag_path: str, experiment_path: str, out_dir: str, method: str = 'lm',
                       progress: Callable[[dict], None] | None = None, diagnose: bool = True) -> dict:
    """Identify the experiment's parameters from the bag; write ``out_dir/report.json`` (+ plots); return the report.

    method: 'lm' (Levenberg-Marquardt, default), 'lbfgsb' (L-BFGS-B with the adjoint gradient) or 'steepest' (the
    paper's projected steepest descent with Armijo steps). diagnose: run the closed loop (effects_added; default on).
    Raises ValueError subclasses on bad input.
    """
    settings = IdentificationSettings(method=method, diagnose=diagnose)
    return identify(bag_path, experiment_path, out_dir, settings, progress).report
