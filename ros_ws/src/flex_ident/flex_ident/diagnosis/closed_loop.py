"""The closed loop on measured data: residual -> the effect the model lacks -> add it -> re-identify -> repeat.

After the declared parameters are identified (``identify``), each round

1. **screens** every remaining candidate effect (:mod:`.effects`) with a score test: one simulation of the current
   model with the residual Jacobian with respect to the current parameters *and* every candidate's coefficients at
   their null values (forward sensitivities; central differences for the time offset). The Gauss-Newton step of a
   candidate's columns, made orthogonal to the current parameters' columns, predicts the drop of the residual sum of
   squares if that effect were added (a Rao score / Lagrange-multiplier test);
2. **fits** the most promising candidates (all with a predicted drop of at least SCREEN_MIN_DROP, at most
   FIT_CANDIDATES; the linear prediction is a ranking, not a verdict) jointly with the current parameters (the same
   Levenberg-Marquardt and sensitivities as the declared identification, from the current optimum and the effect's
   null value);
3. **decides** with the Bayesian information criterion on the residual, with an effective sample count that accounts
   for the residual's correlation in time (simulated trajectories turn white measurement noise into smooth errors,
   so the raw sample count would make every effect look significant):

       dBIC = N_eff ln(RSS_new / RSS_old) + k ln(N_eff),  N_eff = sum over channels T (1 - rho_1) / (1 + rho_1)

   (rho_1: lag-one autocorrelation of the new model's residual, k: the effect's coefficient count). An effect is added
   when dBIC < -BIC_STRONG (strong evidence on Kass and Raftery's scale) *and* it removes at least MIN_RSS_DROP of the
   residual; rounds stop when no candidate passes. Clean data keeps the declared model. When several pass, they are
   compared at one effective sample count; those within BIC_STRONG of the best are indistinguishable, the one with
   the fewest coefficients (then the first in the candidate list) is added and the evidence names the others.

A per-joint friction whose shared variant is already in the model is fitted as its *replacement* (from the shared
value, k counting only the extra coefficients), so the statistics decide between shared and per joint.

After the loop (``identify.add_diagnosis``): every model along the way is refitted on the first part of the window
and measured on the held-out rest (:func:`add_validation`); the final residual is compared with the noise the data
itself shows (:func:`measured_noise_level`), and a residual far above it is reported as a wrong model structure
(:func:`structure_warning`).

Measured time offsets, the loop's mass and a payload are no model terms: :class:`OuterParameterProblem` evaluates
the problem on torques shifted in time by a spline or on a model with changed masses, and adds their
finite-difference columns to the residual Jacobian.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from ..identification.optimizers import levenberg_marquardt
from ..identification.problem import IdentificationProblem, MeasuredData, ParameterTransform
from ..identification.report import hac_parameter_covariance
from .effects import (DELAY_PARAMETER, OUTER_PARAMETERS, Effect, apply_outer_parameters, candidate_effects, describe,
                      reported_parameters, with_effect)

BIC_STRONG = 10.0
MIN_RSS_DROP = 0.02
MAX_ROUNDS = 4
DIAGNOSIS_COST = None            # None: the identification's own cost (end_effector by default)
FIT_CANDIDATES = 4          # at most this many candidates fitted per round (best predicted first) ...
SCREEN_MIN_DROP = 0.005     # ... among those whose predicted residual drop is at least this (the score test can
                            # underpredict damping of lightly damped loop modes by an order of magnitude)


class OuterParameterProblem:
    """An identification problem whose last free parameters may be *outer parameters* (effects.OUTER_PARAMETERS, in
    that order), which are no model coefficients and so have no sensitivities in the compiled kernel:

    * ``delay_s``: the model is driven by tau_meas(t + delay_s) (cubic spline, ends held);
    * ``dm_loop``, ``payload_kg``: the loop's masses x (1 + dm_loop) and a point mass at the grasp frame
      (effects.apply_outer_parameters), i.e. a rebuilt model.

    Each distinct set of outer values gets its own inner IdentificationProblem (the same feedback); the coefficients'
    Jacobian columns are the inner problem's forward sensitivities, each outer parameter's column is a central
    difference with the step effects.OUTER_PARAMETERS gives (two extra simulations each; a one-sided difference when
    one of them fails). Same interface as IdentificationProblem for the optimizers (evaluate, transform, substeps,
    discretization_changed)."""

    def __init__(self, model, data: MeasuredData, free: list, lower, upper, feedback, substeps: int,
                 cost_kind: str, torque_hold: str):
        self.model, self.data, self.feedback = model, data, feedback
        self.free = list(free)
        self.outer = [n for n in OUTER_PARAMETERS if n in self.free]
        if self.free[len(self.free) - len(self.outer):] != self.outer:
            raise ValueError(f'the outer parameters {self.outer} must come last, in this order')
        self.coef_free = self.free[:len(self.free) - len(self.outer)]
        self.transform = ParameterTransform(np.asarray(lower, float), np.asarray(upper, float))
        self.substeps = int(substeps)
        self.cost_kind, self.torque_hold = cost_kind, torque_hold
        self.discretization_changed = False
        self.evaluations = 0
        self._spline = CubicSpline(data.t_s, data.tau, axis=0) if DELAY_PARAMETER in self.outer else None
        self._cache = {}
        self.cost = self._inner((0.0,) * len(self.outer)).cost

    def _inner(self, outer_values) -> IdentificationProblem:
        key = tuple(round(float(v), 12) for v in outer_values)
        if key not in self._cache:
            values = dict(zip(self.outer, key))
            d = self.data
            tau = d.tau
            delay = values.get(DELAY_PARAMETER, 0.0)
            if delay != 0.0:
                t = np.clip(d.t_s + delay, d.t_s[0], d.t_s[-1])
                tau = self._spline(t)
            shifted = MeasuredData(d.t_s, d.names, d.theta, tau)
            lo = np.zeros(len(self.coef_free))
            if len(self._cache) > 8:
                self._cache.clear()
            self._cache[key] = IdentificationProblem(apply_outer_parameters(self.model, values), shifted,
                                                     self.coef_free, lo, lo + np.inf, self.feedback,
                                                     substeps=self.substeps, cost_kind=self.cost_kind,
                                                     torque_hold=self.torque_hold)
        inner = self._cache[key]
        inner.substeps = max(inner.substeps, self.substeps)
        return inner

    def _run(self, outer_values, coefs, jacobian):
        inner = self._inner(outer_values)
        ev = inner.evaluate(coefs, jacobian=jacobian)
        if inner.discretization_changed:
            inner.discretization_changed = False
            self.discretization_changed = True
            self.substeps = max(self.substeps, inner.substeps)
        return ev

    def evaluate(self, params, jacobian: bool = False, gradient: bool = False):
        """As IdentificationProblem.evaluate; the gradient (if asked) is 2 J^T r from the residual Jacobian."""
        ev = self._evaluate(params, jacobian or gradient)
        if gradient and ev.ok:
            ev.gradient = 2.0 * ev.jacobian.T @ ev.residual.ravel()
        return ev

    def _evaluate(self, params, jacobian: bool):
        self.evaluations += 1
        params = np.asarray(params, float)
        n_coef = len(self.coef_free)
        coefs, outer = params[:n_coef], params[n_coef:]
        ev = self._run(outer, coefs, jacobian)
        ev.params = params
        if jacobian and ev.ok and len(self.outer):
            columns = []
            for i, name in enumerate(self.outer):
                step = OUTER_PARAMETERS[name]
                up, down = outer.copy(), outer.copy()
                up[i] += step
                down[i] -= step
                plus, minus = self._run(up, coefs, False), self._run(down, coefs, False)
                if plus.ok and minus.ok:
                    column = (plus.residual - minus.residual).ravel() / (2 * step)
                elif plus.ok or minus.ok:       # one changed simulation failed (a stiff model): one-sided difference
                    column = ((plus.residual - ev.residual) if plus.ok else (ev.residual - minus.residual)).ravel() \
                        / step
                else:
                    column = np.full(ev.residual.size, np.nan)
                columns.append(column)
            ev.jacobian = np.column_stack([ev.jacobian] + columns)
        return ev


def effective_samples(residual) -> float:
    """Sum over residual channels of T (1 - rho_1) / (1 + rho_1), rho_1 the lag-one autocorrelation (AR(1))."""
    r = np.asarray(residual, float)
    r = r.reshape(len(r), -1)
    total = 0.0
    for c in range(r.shape[1]):
        x = r[:, c]
        ss = float(x @ x)
        rho = float(x[1:] @ x[:-1]) / ss if ss > 0 else 0.0
        rho = min(max(rho, 0.0), 0.999)
        total += len(x) * (1 - rho) / (1 + rho)
    return max(total, 2.0)


def delta_bic(rss_old: float, rss_new: float, k: int, n_eff: float) -> float:
    return n_eff * math.log(max(rss_new, 1e-300) / max(rss_old, 1e-300)) + k * math.log(n_eff)


@dataclass
class State:
    """The current model: model, free parameter names (declared + added effects), their values and bounds."""
    model: object
    free: list
    params: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    effects: list = field(default_factory=list)      # accepted Effect objects

    def problem(self, base: IdentificationProblem, extra: list[Effect] = ()) -> 'OuterParameterProblem':
        model, free = self.model, list(self.free)
        lower, upper, params = list(self.lower), list(self.upper), list(self.params)
        for e in extra:
            model = with_effect(model, e)
            free += list(e.coefficients)
            lower += list(e.lower)
            upper += list(e.upper)
            params += list(e.null)
        # the outer parameters, when present, go last (in OUTER_PARAMETERS order)
        for name in OUTER_PARAMETERS:
            if name in free:
                i = free.index(name)
                for seq in (free, lower, upper, params):
                    seq.append(seq.pop(i))
        problem = OuterParameterProblem(model, base.data, free, lower, upper, base.feedback, base.substeps,
                                        base.cost.kind, base.torque_hold)
        problem.start = np.array(params, float)
        return problem


def score_screen(state: State, base: IdentificationProblem, candidates: list[Effect]) -> list[dict]:
    """Predicted residual drop of every candidate from one evaluation with the augmented Jacobian (score test)."""
    problem = state.problem(base, candidates)
    ev = problem.evaluate(problem.start, jacobian=True)
    base.substeps = max(base.substeps, problem.substeps)
    if not ev.ok:
        return []
    r = ev.residual.ravel()
    J = ev.jacobian
    rss = float(r @ r)
    n_eff = effective_samples(ev.residual)
    own = [problem.free.index(n) for n in state.free]
    JB = J[:, own]
    out = []
    for e in candidates:
        cols = [problem.free.index(n) for n in e.coefficients]
        JG = J[:, cols]
        if not (np.all(np.isfinite(JG)) and np.all(np.isfinite(JB))):
            continue
        try:
            coef_b, *_ = np.linalg.lstsq(JB, JG, rcond=None)
            Jp = JG - JB @ coef_b
            step, *_ = np.linalg.lstsq(Jp, -r, rcond=None)
        except np.linalg.LinAlgError:
            continue
        if e.one_sided and not _replaces(state, e) and np.any(step < 0):
            drop = 0.0
        else:
            drop = float(-(2 * r @ (Jp @ step) + (Jp @ step) @ (Jp @ step)))
        drop = min(max(drop, 0.0), rss)
        out.append({'effect': e, 'predicted_rss_drop': drop / rss if rss > 0 else 0.0,
                    'predicted_step': step.tolist(),
                    'predicted_dbic': delta_bic(rss, rss - drop, e.size, n_eff)})
    out.sort(key=lambda s: s['predicted_dbic'])
    return out


def _replaces(state: State, effect: Effect) -> Effect | None:
    """The shared effect of the current model that the per-joint ``effect`` would replace, if any."""
    for e in state.effects:
        if effect.replaces and e.key == effect.replaces:
            return e
    return None


def _replaced_state(state: State, base: IdentificationProblem, effect: Effect) -> State:
    """The current model with its shared effect replaced, in place, by the per-joint ``effect`` at the shared value."""
    shared = _replaces(state, effect)
    value = float(state.params[state.free.index(shared.coefficients[0])])
    values = dict(zip(state.free, (float(v) for v in state.params)))
    values.update({c: value for c in effect.coefficients})
    return _state_with(base, [effect if e.key == shared.key else e for e in state.effects], values)


def fit_with(state: State, base: IdentificationProblem, effect: Effect, step=None, max_iterations: int = 20):
    """Joint fit of the current parameters and the effect's coefficients (LM), from the current optimum and the
    effect's null value, or from the score test's Gauss-Newton ``step`` when that is better (nonsmooth effects such as
    Coulomb friction can stall in a poor local minimum from the null value). A per-joint effect whose shared variant
    is in the model replaces it and starts from the shared value."""
    if _replaces(state, effect) is not None:
        return _fit_state(_replaced_state(state, base, effect), base)
    problem = state.problem(base, [effect])
    start = problem.start
    if step is not None:
        cols = [problem.free.index(n) for n in effect.coefficients]
        lo, hi = problem.transform.lower[cols], problem.transform.upper[cols]
        trial = start.copy()
        trial[cols] = np.clip(start[cols] + np.asarray(step, float), lo, hi)
        a = problem.evaluate(start)
        b = problem.evaluate(trial)
        if b.ok and (not a.ok or b.cost < a.cost):
            start = trial
    result = levenberg_marquardt(problem, start, max_iterations=max_iterations, rescue_above=None)
    base.substeps = max(base.substeps, problem.substeps)
    return problem, result


def _errors(problem, ev) -> dict:
    return problem.cost.errors(ev.traj.q)


def _entry(e: Effect, fitted, result, before, dbic, n_eff, drop, how: str, declared: list) -> dict:
    """One effects_added item (CONTRACTS.md section 3) from the joint fit that added effect ``e``."""
    ev = result.evaluation
    values = [result.params[fitted.free.index(n)] for n in e.coefficients]
    std, _, _ = hac_parameter_covariance(ev.jacobian, ev.residual)
    std_map = dict(zip(fitted.free, std))
    return {
        'name': e.name, 'key': e.key,
        'parameters': reported_parameters(e, values),
        'coefficients': dict(zip(e.coefficients, (float(v) for v in values))),
        'coefficient_std': {n: float(std_map[n]) for n in e.coefficients},
        'evidence': (f'{describe(e, values)}. Residual sum of squares {100 * drop:.1f} % lower; BIC change '
                     f'{dbic:.1f} with {n_eff:.0f} effective samples (strong evidence below -{BIC_STRONG:g}); {how}.'),
        'error_before': _errors(fitted, before),
        'error_after': _errors(fitted, ev),
        'declared_parameters_after': {n: float(result.params[fitted.free.index(n)]) for n in declared},
        'declared_parameter_std': {n: float(std_map[n]) for n in declared},
    }


def _state_with(base: IdentificationProblem, effects: list[Effect], values: dict) -> State:
    """The declared model plus ``effects`` (in order), parameters from ``values`` (name -> value) or null values."""
    tf = base.transform
    state = State(base.model, list(base.free), np.array([values[n] for n in base.free], float),
                  np.asarray(tf.lower, float), np.asarray(tf.upper, float))
    for e in effects:
        state = State(with_effect(state.model, e), state.free + list(e.coefficients),
                      np.concatenate([state.params, [values.get(n, v) for n, v in zip(e.coefficients, e.null)]]),
                      np.concatenate([state.lower, e.lower]), np.concatenate([state.upper, e.upper]),
                      state.effects + [e])
    return state


def _at_implausible_bound(fitted, result, effects: list[Effect]) -> list[str]:
    """The effects' coefficients that the fit left at a bound other than their null value (an 80 % lighter loop, a
    gain of 5, a 0.1 s delay): such a fit does not estimate the effect, it uses it to absorb something else (e.g.
    seven torque biases and a loop mass at its bound trading a little model mismatch), so it is not accepted."""
    out = []
    lower, upper = fitted.transform.lower, fitted.transform.upper
    for e in effects:
        for name, null in zip(e.coefficients, e.null):
            if name not in fitted.free:         # a shared friction this fit replaces
                continue
            i = fitted.free.index(name)
            lo, hi, v = lower[i], upper[i], float(result.params[i])
            if not (np.isfinite(lo) and np.isfinite(hi)):
                continue
            tol = 1e-3 * (hi - lo)
            if (lo != null and v <= lo + tol) or (hi != null and v >= hi - tol):
                out.append(name)
    return out


def _choose(passed: list, rss_old: float, state: State, pool: list):
    """The effect to add among the round's accepted fits (tuples (effect, problem, result, dBIC, N_eff, drop, screen)),
    and those the data cannot tell from it. The fits are compared at one effective sample count (the smallest of
    theirs: a BIC comparison needs the same N, and each fit's own N_eff differs by its residual's correlation); those
    within BIC_STRONG of the best are indistinguishable, and among them the one with the fewest (extra) coefficients,
    then the first in the candidate list, is chosen (e.g. a loop-mass error and a payload at the gripper both load
    the arm mostly through gravity; the loop's declared mass comes first)."""
    n_common = min(p[4] for p in passed)

    def extra(e):
        shared = _replaces(state, e)
        return e.size - (shared.size if shared else 0)

    common = [delta_bic(rss_old, p[2].evaluation.cost, extra(p[0]), n_common) for p in passed]
    lowest = min(common)
    alike = [p for p, d in zip(passed, common) if d <= lowest + BIC_STRONG]
    order = [c.key for c in pool]
    best = min(alike, key=lambda p: (extra(p[0]), order.index(p[0].key) if p[0].key in order else len(order)))
    return best, [p for p in alike if p is not best]


def _accept(dbic: float, drop: float) -> bool:
    return dbic < -BIC_STRONG and drop >= MIN_RSS_DROP


def _fit_state(state: State, base: IdentificationProblem):
    problem = state.problem(base)
    result = levenberg_marquardt(problem, problem.start, max_iterations=20, rescue_above=None)
    base.substeps = max(base.substeps, problem.substeps)
    return problem, result


def diagnose(problem: IdentificationProblem, params, progress=None, candidates: list[Effect] | None = None,
             max_rounds: int = MAX_ROUNDS, cost: str | None = DIAGNOSIS_COST) -> dict:
    """Run the closed loop from identified declared parameters ``params`` (of ``problem.free``).

    Forward selection (score screening, joint fits, BIC) with a backward step: after an effect is added, every
    earlier one is refitted out and dropped unless the evidence still demands it (a greedy first choice, e.g. seven
    torque biases standing in for one sensor gain and some damping, is undone). If anything was dropped, the final
    set is replayed in order from the declared fit so that each item's error_before/after is its own.

    Returns {'effects_added': [...CONTRACTS section 3...], 'parameters': final declared + effect coefficients,
    'error_after': final errors, 'rounds': screening/decision log, 'wall_time_s'}.

    cost: the residual the diagnosis works on (None: the identification's; otherwise the declared parameters are
    first refitted on it). Measured on 18 recordings (docs/CLOSED_LOOP_STATUS.md): the end-effector cost names the
    right effects in all; 'joint_angles' recovers arm friction and per-joint torque biases more accurately but
    takes a torque sensor gain for biases on the gravity-loaded joints and misses loop damping on the 12-link loop."""
    t0 = time.monotonic()
    if cost is not None and problem.cost.kind != cost:
        problem = IdentificationProblem(problem.model, problem.data, problem.free, problem.transform.lower,
                                        problem.transform.upper, problem.feedback, substeps=problem.substeps,
                                        cost_kind=cost, torque_hold=problem.torque_hold,
                                        max_substeps=problem.max_substeps)
        params = levenberg_marquardt(problem, params, max_iterations=20, rescue_above=None).params
    values = dict(zip(problem.free, (float(v) for v in params)))
    state = _state_with(problem, [], values)
    declared_eval = state.problem(problem).evaluate(state.params, jacobian=False)
    current = declared_eval
    pool = list(candidates if candidates is not None else candidate_effects(problem.model))
    added, rounds, dropped_any = [], [], False
    final_free = list(problem.free)
    for round_no in range(max_rounds):
        keys = {e.key for e in state.effects} | {e.replaces for e in state.effects}
        remaining = [c for c in pool if c.key not in keys]
        if not remaining:
            break
        if progress:
            progress({'stage': 'diagnose', 'round': round_no + 1, 'fraction': 0.0})
        screen = score_screen(state, problem, remaining)
        log = {'round': round_no + 1, 'rss_before': float(current.cost),
               'screening': [{'effect': s['effect'].key, 'predicted_rss_drop': round(s['predicted_rss_drop'], 4),
                              'predicted_dbic': round(s['predicted_dbic'], 1)} for s in screen],
               'fits': []}
        rounds.append(log)
        passed = []
        for s in screen[:FIT_CANDIDATES]:
            if s['predicted_rss_drop'] < SCREEN_MIN_DROP:
                continue
            e = s['effect']
            fitted, result = fit_with(state, problem, e, s['predicted_step'])
            ev = result.evaluation
            if not ev.ok:
                continue
            n_eff = effective_samples(ev.residual)
            shared = _replaces(state, e)
            dbic = delta_bic(current.cost, ev.cost, e.size - (shared.size if shared else 0), n_eff)
            drop = 1.0 - ev.cost / current.cost if current.cost > 0 else 0.0
            at_bound = _at_implausible_bound(fitted, result, state.effects + [e])
            log['fits'].append({'effect': e.key, 'rss_drop': round(drop, 4), 'dbic': round(dbic, 1),
                                'n_eff': round(n_eff, 1), 'iterations': int(result.iterations),
                                'parameters': dict(zip(fitted.free, (float(v) for v in result.params)))})
            if at_bound:
                log['fits'][-1]['rejected'] = f'{", ".join(at_bound)} at the end of the plausible range'
            elif _accept(dbic, drop):
                passed.append((e, fitted, result, dbic, n_eff, drop, s))
        if not passed:
            log['decision'] = 'no candidate passes (dBIC < -%g and residual drop >= %g)' % (BIC_STRONG, MIN_RSS_DROP)
            break
        best, alike = _choose(passed, current.cost, state, pool)
        e, fitted, result, dbic, n_eff, drop, s = best
        how = (f'the score test ranked it {screen.index(s) + 1} of {len(screen)} candidates (predicted '
               f'{100 * s["predicted_rss_drop"]:.1f} % drop)')
        if alike:
            log['indistinguishable'] = [a[0].key for a in alike]
            others = ', '.join(f'{a[0].key} ({100 * a[5]:.1f} % lower)' for a in alike)
            how += (f'; the data hardly tell it from {others}'
                    + f' (BIC within {BIC_STRONG:g} at a common effective sample count), and it has the fewest '
                    'coefficients or comes first in the candidate list among them')
        shared = _replaces(state, e)
        values = dict(zip(fitted.free, (float(v) for v in result.params)))
        if shared is None:
            added.append(_entry(e, fitted, result, current, dbic, n_eff, drop, how, problem.free))
            log['decision'] = f'added {e.key}'
            state = _state_with(problem, state.effects + [e], values)
        else:                   # per-joint values replace the shared one, in place (the statistics decided)
            at = [x.key for x in state.effects].index(shared.key)
            was = describe(shared, [state.params[state.free.index(c)] for c in shared.coefficients])
            how = f'it replaces the shared {shared.key} ({was}); {how}'
            entry = _entry(e, fitted, result, current, dbic, n_eff, drop, how, problem.free)
            entry['error_before'] = added[at]['error_before']       # the model without this friction at all
            added[at] = entry
            log['decision'] = f'replaced {shared.key} by {e.key}'
            state = _state_with(problem, [e if x.key == shared.key else x for x in state.effects], values)
        current, final_free = result.evaluation, list(fitted.free)
        # backward step
        for old in [x for x in state.effects if x.key != e.key]:
            reduced = _state_with(problem, [x for x in state.effects if x.key != old.key], values)
            r_problem, r_result = _fit_state(reduced, problem)
            r_ev = r_result.evaluation
            if not r_ev.ok:
                continue
            n_eff = effective_samples(current.residual)
            keep_dbic = delta_bic(r_ev.cost, current.cost, old.size, n_eff)
            keep_drop = 1.0 - current.cost / r_ev.cost if r_ev.cost > 0 else 0.0
            log.setdefault('backward', []).append({'effect': old.key, 'dbic_to_keep': round(keep_dbic, 1),
                                                   'rss_drop_to_keep': round(keep_drop, 4)})
            if not _accept(keep_dbic, keep_drop):
                dropped_any = True
                log['decision'] += f', dropped {old.key}'
                values = dict(zip(r_problem.free, (float(v) for v in r_result.params)))
                state = _state_with(problem, reduced.effects, values)
                current, final_free = r_ev, list(r_problem.free)
    if dropped_any:
        added = _replay(problem, state.effects, declared_eval, dict(zip(problem.free, (float(v) for v in params))))
    if added:
        # every effect's parameters as identified jointly in the final model (the values when it was added are kept)
        final = dict(zip(final_free, (float(v) for v in current.params)))
        std, _, _ = hac_parameter_covariance(current.jacobian, current.residual)
        std = dict(zip(final_free, (float(v) for v in std)))
        for entry, e in zip(added, state.effects):
            entry['parameters_when_added'] = entry['parameters']
            entry['parameters'] = reported_parameters(e, [final[n] for n in e.coefficients])
            entry['coefficients'] = {n: final[n] for n in e.coefficients}
            entry['coefficient_std'] = {n: std[n] for n in e.coefficients}
    return {'effects_added': added, 'parameters': dict(zip(state.free, (float(v) for v in state.params))),
            'error_after': problem.cost.errors(current.traj.q), 'rounds': rounds, 'cost': problem.cost.kind,
            'declared_refit': dict(zip(problem.free, (float(v) for v in params))),
            'wall_time_s': time.monotonic() - t0, '_effects': list(state.effects)}


NOISE_WINDOW_S = 0.1          # Savitzky-Golay window of the noise-level estimate (the motion is far slower)
STRUCTURE_RATIO = 3.0         # final end-effector residual above this many times the data's noise: wrong model


def measured_noise_level(base: IdentificationProblem) -> dict:
    """The noise the measurement itself shows, with no model: the measured arm angles and the end-effector path
    computed from them, minus their Savitzky-Golay smoothing (cubic, NOISE_WINDOW_S), corrected for the share of the
    noise the smoother keeps (:func:`~.arm_torque.torque_noise_rms`). A model that explains the data leaves about
    this much; ee_rms_m is comparable with the errors' ee_rms_m (RMS of the 3-D distance)."""
    from .arm_torque import torque_noise_rms
    w = max(5, int(round(NOISE_WINDOW_S / base.data.dt)) | 1)
    ee = torque_noise_rms(base.cost.y_meas, w) * math.sqrt(base.cost.y_meas.shape[1])
    joint = torque_noise_rms(base.cost.theta_meas, w)
    return {'ee_rms_m': float(ee), 'joint_rms_rad': float(joint), 'window_samples': int(w)}


def structure_warning(error_after: dict, noise: dict, effects_added: list) -> str | None:
    """Plain words when the final model still leaves far more than the noise (STRUCTURE_RATIO) after the closed
    loop: no candidate effect explains the rest, so the model's structure is wrong."""
    ratio = error_after['ee_rms_m'] / max(noise['ee_rms_m'], 1e-12)
    if ratio <= STRUCTURE_RATIO:
        return None
    named = (f'after adding {", ".join(e["key"] for e in effects_added)}' if effects_added
             else 'and no candidate effect explains it')
    return (f'the model structure looks wrong: the end-effector residual is {1e3 * error_after["ee_rms_m"]:.3g} mm, '
            f'{ratio:.0f} times the noise the data itself shows ({1e3 * noise["ee_rms_m"]:.3g} mm), {named}. Check '
            f'the experiment against the hardware (number of loop links, radius, mass, grasp and clamp poses, the '
            f'arm description) or look for an effect outside the closed loop\'s library; the identified parameters '
            f'of this model should not be trusted')


def validation_split(base: IdentificationProblem, fraction: float) -> int:
    """Samples of the fitted part when the last ``fraction`` of the window is held out (never fitted)."""
    T = len(base.data.t_s)
    n_fit = T - int(round(fraction * T))
    if not 0.0 < fraction < 1.0 or n_fit < 20 or T - n_fit < 10:
        raise ValueError(f'validation fraction {fraction:g} leaves no usable fitted part or validation part of the '
                         f'{T} samples')
    return n_fit


def held_out_errors(state: State, base: IdentificationProblem, n_fit: int, max_iterations: int = 15) -> dict:
    """The model of ``state`` refitted on the first ``n_fit`` samples only (LM from the state's parameters), then
    simulated over the whole window: its errors on the held-out rest ('ee_rms_m', 'joint_rms_rad'), with the fitted
    part's beside them ('fitted_part'). When that simulation fails (the refitted model leaves its valid region in
    the held-out part), the errors are None and 'failure' says why."""
    fit_problem = state.problem(base.truncated(n_fit))
    result = levenberg_marquardt(fit_problem, fit_problem.start, max_iterations=max_iterations, rescue_above=None)
    full = state.problem(base)
    full.substeps = max(full.substeps, fit_problem.substeps)
    ev = full.evaluate(result.params if result.evaluation.ok else fit_problem.start)
    if not ev.ok:
        return {'ee_rms_m': None, 'joint_rms_rad': None, 'failure': str(ev.failure)}
    out = base.cost.errors(ev.traj.q, slice(n_fit, None))
    out['fitted_part'] = base.cost.errors(ev.traj.q, slice(0, n_fit))
    return out


def add_validation(found: dict, base: IdentificationProblem, fraction: float, effects: list[Effect],
                   declared_values: dict, progress=None) -> dict:
    """Validation figures of the declared model and of each model along ``effects_added`` (each refitted on the
    fitted part, measured on the held-out last ``fraction`` of the window): put into every item's error_before /
    error_after under 'validation'; returns {'declared': ..., 'final': ..., 'fraction', 'from_s'}."""
    n_fit = validation_split(base, fraction)
    values = dict(declared_values)
    values.update(found['parameters'])
    figures = []
    for i in range(len(effects) + 1):
        if progress:
            progress({'stage': 'validate', 'fraction': i / (len(effects) + 1)})
        state = _state_with(base, effects[:i], values if i else declared_values)
        figures.append(held_out_errors(state, base, n_fit))
    for i, entry in enumerate(found['effects_added']):
        entry['error_before']['validation'] = figures[i]
        entry['error_after']['validation'] = figures[i + 1]
        before, after = figures[i]['ee_rms_m'], figures[i + 1]['ee_rms_m']
        entry['lowers_validation_error'] = None if before is None or after is None else bool(after < before)
    return {'declared': figures[0], 'final': figures[-1], 'fraction': float(fraction),
            'from_s': float(base.data.t_s[n_fit] - base.data.t_s[0]), 'fitted_samples': int(n_fit)}


def _replay(problem, effects, declared_eval, values) -> list:
    """Effects_added entries for the final effect set, added in order from the declared fit."""
    out, current, state = [], declared_eval, _state_with(problem, [], values)
    for e in effects:
        fitted, result = fit_with(state, problem, e)
        ev = result.evaluation
        n_eff = effective_samples(ev.residual)
        dbic = delta_bic(current.cost, ev.cost, e.size, n_eff)
        drop = 1.0 - ev.cost / current.cost if current.cost > 0 else 0.0
        out.append(_entry(e, fitted, result, current, dbic, n_eff, drop,
                          'kept by the backward step (an effect chosen earlier was dropped)', problem.free))
        values = dict(zip(fitted.free, (float(v) for v in result.params)))
        state = _state_with(problem, state.effects + [e], values)
        current = ev
    return out
