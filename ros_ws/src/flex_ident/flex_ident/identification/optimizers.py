"""Optimizers for the identification problem, all with hard bounds and a per-iteration callback.

* ``levenberg_marquardt`` (default, 'lm'): Gauss-Newton on the stacked residual with Marquardt's scaled damping and a
  gain-ratio trust region, steps clipped to the bounds; uses the exact residual Jacobian (forward sensitivities).
  Converges in a handful of iterations on this problem.
* ``lbfgsb`` ('lbfgsb'): scipy's L-BFGS-B on J with the adjoint gradient (paper Lemma 1).
* ``steepest_descent`` ('steepest', the paper's baseline, Sec. IV-E): projected steepest descent with Armijo
  backtracking in the original parameter units (p_{i+1} = Proj(p_i - s beta^m grad J)).

They work in the transformed variables z of :class:`~.problem.ParameterTransform` (except the baseline, which
works in the parameters' own units, as the paper does) and return an :class:`OptimizationResult`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

METHODS = ('lm', 'lbfgsb', 'steepest')
ALIASES = {'levenberg-marquardt': 'lm', 'gauss-newton': 'lm', 'gn': 'lm', 'adjoint': 'lbfgsb', 'l-bfgs-b': 'lbfgsb',
           'lbfgs': 'lbfgsb', 'armijo': 'steepest', 'steepest-descent': 'steepest', 'sd': 'steepest'}


def canonical_method(method: str) -> str:
    m = str(method).strip().lower()
    m = ALIASES.get(m, m)
    if m not in METHODS:
        raise ValueError(f'unknown optimization method "{method}": use one of {", ".join(METHODS)} '
                         f'(aliases: {", ".join(sorted(ALIASES))})')
    return m


@dataclass
class OptimizationResult:
    params: np.ndarray                          # final coefficient values
    evaluation: object                          # Evaluation at params (with jacobian when available)
    iterations: int
    history: list = field(default_factory=list)  # per iteration: {'iteration', 'cost', 'params', 'evaluations'}
    converged: bool = False
    message: str = ''
    evaluations: int = 0


def _record(history, iteration, ev, n_evals, callback, max_iterations):
    entry = {'iteration': iteration, 'cost': float(ev.cost), 'params': [float(v) for v in ev.params],
             'evaluations': n_evals}
    history.append(entry)
    if callback is not None:
        callback(dict(entry, fraction=min(1.0, iteration / max(1, max_iterations)), evaluation=ev))


#: an optimizer about to stop while the cost is still above this fraction of the initial cost scans for a better start
RESCUE_COST_FRACTION = 0.5


def _small(step, z, xtol):
    return np.max(np.abs(step)) < xtol * (1.0 + np.max(np.abs(z)))


def levenberg_marquardt(problem, p0, max_iterations=30, callback=None, xtol=1e-5, ftol=1e-6, rescue_above='auto'):
    """Bounded Levenberg-Marquardt in z space. ``problem.evaluate(params, jacobian=True)``.

    rescue_above: about to stop with the cost still above this value, scan the parameters on a log scale once and go
    on from the best point ('auto': RESCUE_COST_FRACTION x the initial cost; None: never)."""
    tf = problem.transform
    lo, hi = tf.z_bounds()
    z = np.clip(tf.to_z(p0), lo, hi)
    ev = problem.evaluate(tf.to_c(z), jacobian=True)
    n_evals = 1
    if not ev.ok:
        raise RuntimeError(f'the model cannot be simulated at the initial parameters: {ev.failure}')
    problem.discretization_changed = False
    history = []
    _record(history, 0, ev, n_evals, callback, max_iterations)
    if rescue_above == 'auto':
        rescue_above = RESCUE_COST_FRACTION * ev.cost
    mu = 1e-3
    converged, message = False, f'stopped after {max_iterations} iterations'
    it = 0
    rescued = False

    def linear_model(ev, z):
        r = ev.residual.ravel()
        Jz = ev.jacobian * tf.dc_dz(z)[None, :]
        JTJ = Jz.T @ Jz
        scale = np.maximum(np.diag(JTJ), 1e-12 * max(np.max(np.diag(JTJ)), 1e-300))
        return Jz.T @ r, JTJ, scale

    while it < max_iterations:
        if ev.cost == 0.0:
            converged, message = True, 'zero cost'
            break
        g, JTJ, scale = linear_model(ev, z)
        accepted = False
        tries = 0
        while tries < 12:
            tries += 1
            if not (np.all(np.isfinite(g)) and np.all(np.isfinite(JTJ))):
                break                      # sensitivities overflowed: leave it to the log-scale scan below
            step = np.linalg.solve(JTJ + mu * np.diag(scale), -g)
            z_new = np.clip(z + step, lo, hi)
            step = z_new - z
            if not np.any(step):
                break
            predicted = -(2 * g @ step + step @ JTJ @ step)       # |r|^2 - |r + J step|^2
            trial = problem.evaluate(tf.to_c(z_new), jacobian=True)
            n_evals += 1
            if getattr(problem, 'discretization_changed', False):
                # a finer VI step was needed: the cost function changed slightly; re-evaluate where we stand
                problem.discretization_changed = False
                ev = problem.evaluate(tf.to_c(z), jacobian=True)
                n_evals += 1
                g, JTJ, scale = linear_model(ev, z)
                continue
            actual = ev.cost - trial.cost if trial.ok else -np.inf
            rho = actual / predicted if predicted > 0 else -np.inf
            if trial.ok and actual > 0 and rho > 1e-4:
                accepted = True
                mu = mu * max(1 / 3, 1 - (2 * rho - 1) ** 3) if rho > 0.25 else mu * 2
                break
            mu *= 4.0
        if accepted:
            small_step = _small(step, z, xtol)
            small_decrease = ev.cost - trial.cost <= ftol * ev.cost
            it += 1
            z, ev = z_new, trial
            _record(history, it, ev, n_evals, callback, max_iterations)
            if not (small_step or small_decrease):
                continue
            stop = f'step below {xtol:g} (relative)' if small_step else f'relative cost decrease below {ftol:g}'
        else:
            stop = 'no further decrease (local minimum at the resolution of the cost)'
        if not rescued and rescue_above is not None and ev.cost > rescue_above:
            # stopping while the fit is hardly better than the initial guess: far from the truth the loop can
            # move chaotically, its sensitivities explode and only tiny LM steps succeed. Scan the whole parameter
            # vector on a log scale and go on from the best point, once.
            rescued = True
            best, n = _log_scan(problem, z, lo, hi, ev)
            n_evals += n
            if best is not None:
                it += 1
                z, ev = best
                mu = 1e-3
                _record(history, it, ev, n_evals, callback, max_iterations)
                continue
        converged, message = True, stop
        break
    return OptimizationResult(params=tf.to_c(z), evaluation=ev, iterations=it, history=history, converged=converged,
                              message=message, evaluations=n_evals)


def _log_scan(problem, z, lo, hi, ev, factors=(-2.0, -1.0, -0.5, 0.5, 1.0, 2.0)):
    """Evaluate the parameters scaled together by 10^f (or shifted for linear ones); return ((z, evaluation) of
    the best improvement or None, number of evaluations)."""
    tf = problem.transform
    best, n = None, 0
    for f in factors:
        z_try = np.clip(z + np.where(tf.log, f * np.log(10.0), f * np.maximum(1.0, np.abs(z))), lo, hi)
        if np.allclose(z_try, z):
            continue
        trial = problem.evaluate(tf.to_c(z_try), jacobian=True)
        n += 1
        if getattr(problem, 'discretization_changed', False):
            problem.discretization_changed = False
        if trial.ok and np.all(np.isfinite(trial.jacobian)) and trial.cost < (best[1].cost if best else ev.cost):
            best = (z_try, trial)
    return best, n


def lbfgsb(problem, p0, max_iterations=100, callback=None):
    """L-BFGS-B on J(z) with the adjoint gradient."""
    tf = problem.transform
    lo, hi = tf.z_bounds()
    cache = {}
    n_evals = [0]

    def fun(z):
        key = tuple(np.round(z, 15))
        if key not in cache:
            ev = problem.evaluate(tf.to_c(z), gradient=True)
            n_evals[0] += 1
            cache.clear()
            cache[key] = ev
        ev = cache[key]
        if not ev.ok:
            return 1e300, np.zeros_like(z)
        return ev.cost, ev.gradient * tf.dc_dz(z)

    z0 = np.clip(tf.to_z(p0), lo, hi)
    history = []
    first = problem.evaluate(tf.to_c(z0), gradient=True)
    n_evals[0] += 1
    if not first.ok:
        raise RuntimeError(f'the model cannot be simulated at the initial parameters: {first.failure}')
    cache[tuple(np.round(z0, 15))] = first
    _record(history, 0, first, n_evals[0], callback, max_iterations)
    state = {'it': 0}

    def cb(zk):
        state['it'] += 1
        ev = cache.get(tuple(np.round(zk, 15))) or problem.evaluate(tf.to_c(zk), gradient=True)
        _record(history, state['it'], ev, n_evals[0], callback, max_iterations)

    bounds = [(a, b if np.isfinite(b) else None) for a, b in zip(lo, hi)]
    res = minimize(fun, z0, jac=True, method='L-BFGS-B', bounds=bounds, callback=cb,
                   options={'maxiter': max_iterations, 'ftol': 1e-12, 'gtol': 1e-12 * max(first.cost, 1e-30)})
    final = problem.evaluate(tf.to_c(res.x), jacobian=True)
    n_evals[0] += 1
    return OptimizationResult(params=tf.to_c(res.x), evaluation=final, iterations=int(res.nit), history=history,
                              converged=bool(res.success), message=str(res.message), evaluations=n_evals[0])


def steepest_descent(problem, p0, max_iterations=100, callback=None, alpha=0.1, beta=0.5, max_backtracks=30):
    """The paper's baseline: projected steepest descent with Armijo steps, in the parameters' own units."""
    lower, upper = problem.transform.lower, problem.transform.upper
    p = np.clip(np.asarray(p0, float), lower, upper)
    ev = problem.evaluate(p, gradient=True)
    n_evals = 1
    if not ev.ok:
        raise RuntimeError(f'the model cannot be simulated at the initial parameters: {ev.failure}')
    history = []
    _record(history, 0, ev, n_evals, callback, max_iterations)
    g = ev.gradient
    s = 0.1 * max(np.linalg.norm(p), 1.0) / max(np.linalg.norm(g), 1e-300)   # first trial moves p by ~10 %
    converged, message = False, f'stopped after {max_iterations} iterations'
    it = 0
    while it < max_iterations:
        g = ev.gradient
        if np.linalg.norm(g) == 0.0:
            converged, message = True, 'gradient vanished'
            break
        accepted = False
        for _ in range(max_backtracks):
            p_new = np.clip(p - s * g, lower, upper)
            trial = problem.evaluate(p_new, gradient=True)
            n_evals += 1
            if trial.ok and trial.cost <= ev.cost - alpha * g @ (p - p_new):
                accepted = True
                break
            s *= beta
        if not accepted:
            converged, message = True, 'Armijo line search found no decrease'
            break
        it += 1
        step = p_new - p
        p, ev = p_new, trial
        _record(history, it, ev, n_evals, callback, max_iterations)
        if np.max(np.abs(step) / np.maximum(np.abs(p), 1e-12)) < 1e-7:
            converged, message = True, 'step below 1e-7 (relative)'
            break
        s /= beta          # try a longer step next time
    final = problem.evaluate(p, jacobian=True)
    n_evals += 1
    return OptimizationResult(params=p, evaluation=final, iterations=it, history=history, converged=converged,
                              message=message, evaluations=n_evals)


def optimize(problem, p0, method='lm', max_iterations=None, callback=None, rescue_above='auto') -> OptimizationResult:
    """rescue_above: see :func:`levenberg_marquardt` (the other methods have no rescue)."""
    method = canonical_method(method)
    if method == 'lm':
        return levenberg_marquardt(problem, p0, max_iterations or 30, callback, rescue_above=rescue_above)
    if method == 'lbfgsb':
        return lbfgsb(problem, p0, max_iterations or 100, callback)
    return steepest_descent(problem, p0, max_iterations or 100, callback)
