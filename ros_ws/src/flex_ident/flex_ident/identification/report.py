"""The identification report (CONTRACTS.md section 3) and parameter uncertainty.

Standard deviations come from the curvature of the cost at the optimum (Gauss-Newton approximation of the Hessian):
cov = sigma^2 (J_r^T J_r)^{-1} with J_r the residual Jacobian and sigma^2 = |r|^2 / (N - p) the residual variance
(N residuals, p parameters). Residuals are correlated in time (the simulation filters the noise), so these are
lower bounds of the true spread; the report says so.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np


def parameter_covariance(jacobian, residual):
    """(std (p,), correlation (p, p)) from the residual Jacobian dr/dc (N, p) and the residual r (N,)."""
    J = np.asarray(jacobian, float)
    r = np.asarray(residual, float).ravel()
    N, p = J.shape
    sigma2 = float(r @ r) / max(N - p, 1)
    JTJ = J.T @ J
    try:
        cov = sigma2 * np.linalg.inv(JTJ)
    except np.linalg.LinAlgError:
        return np.full(p, np.inf), np.full((p, p), np.nan)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid='ignore', divide='ignore'):
        corr = cov / np.outer(std, std)
    return std, corr


def hac_parameter_covariance(jacobian, residual, lag: int | None = None):
    """(std (p,), correlation (p, p), lag) with a Newey-West (HAC) sandwich for residuals correlated in time.

    residual: (T, m), one row per sample; jacobian: (T * m, p), rows in the same (row-major) order. The scores
    g_t = J_t^T r_t of each sample are autocorrelated (a simulated trajectory turns white measurement noise into
    smooth errors), so sigma^2 (J^T J)^-1 is only a lower bound. The sandwich is
    (J^T J)^-1 [sum_{|l| <= L} (1 - |l| / (L + 1)) Gamma_l] (J^T J)^-1 with Gamma_l = sum_t g_t g_{t-l}^T (Bartlett
    weights keep it positive semi-definite). The lag L defaults to Andrews' (1991) AR(1) plug-in bandwidth for the
    Bartlett kernel, 1.1447 (alpha T)^(1/3), alpha = sum 4 rho^2 s^4 / ((1 - rho)^6 (1 + rho)^2) / sum s^4 / (1 - rho)^4
    over the score components (rho their lag-one autocorrelation, s^2 their innovation variance), capped at T / 4."""
    r = np.asarray(residual, float)
    T = r.shape[0]
    r = r.reshape(T, -1)
    J = np.asarray(jacobian, float).reshape(T, r.shape[1], -1)
    p = J.shape[2]
    g = np.einsum('tmp,tm->tp', J, r)
    g = g - g.mean(axis=0)
    if lag is None:
        num = den = 0.0
        for k in range(p):
            x = g[:, k]
            ss = float(x[:-1] @ x[:-1])
            rho = float(x[1:] @ x[:-1]) / ss if ss > 0 else 0.0
            rho = min(max(rho, -0.97), 0.97)
            s2 = float(np.mean((x[1:] - rho * x[:-1]) ** 2))
            num += 4 * rho ** 2 * s2 ** 2 / ((1 - rho) ** 6 * (1 + rho) ** 2)
            den += s2 ** 2 / (1 - rho) ** 4
        alpha = num / den if den > 0 else 0.0
        lag = int(min(max(math.ceil(1.1447 * (alpha * T) ** (1 / 3)), 1), T // 4))
    S = g.T @ g
    for l_ in range(1, lag + 1):
        G = g[l_:].T @ g[:-l_]
        S += (1 - l_ / (lag + 1)) * (G + G.T)
    JTJ = np.einsum('tmp,tmq->pq', J, J)
    try:
        inv = np.linalg.inv(JTJ)
    except np.linalg.LinAlgError:
        return np.full(p, np.inf), np.full((p, p), np.nan), lag
    cov = inv @ S @ inv * T / max(T - p, 1)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid='ignore', divide='ignore'):
        corr = cov / np.outer(std, std)
    return std, corr, lag


def _finite(x):
    x = float(x)
    return x if math.isfinite(x) else None


def build_report(problem, result, initial, experiment, bag_path, method, notes, wall_time_s) -> dict:
    model = problem.model
    final = result.evaluation
    names = problem.free
    std, corr, lag = hac_parameter_covariance(final.jacobian, final.residual)
    curvature_std, _ = parameter_covariance(final.jacobian, final.residual)
    coefs = {c.name: c for c in model.coefficients}
    specs = {p.name: p for p in experiment.identify.parameters}
    report = {
        'parameters': {n: float(v) for n, v in zip(names, result.params)},
        'parameter_std': {n: _finite(s) for n, s in zip(names, std)},
        'error_before': problem.cost.errors(initial.traj.q),
        'error_after': problem.cost.errors(final.traj.q),
        'effects_added': [],
        'iterations': int(result.iterations),
        'wall_time_s': float(wall_time_s),
        'method': method,
        'converged': bool(result.converged),
        'convergence_message': result.message,
        'cost': {'kind': problem.cost.kind, 'initial': float(initial.cost), 'final': float(final.cost),
                 'definition': ('mean over samples of |end-effector position error|^2 [m^2]'
                                if problem.cost.kind == 'end_effector'
                                else 'mean over samples of the summed squared arm-angle errors [rad^2]')},
        'history': [{'iteration': h['iteration'], 'cost': h['cost'],
                     'parameters': dict(zip(names, h['params']))} for h in result.history],
        'simulations': int(result.evaluations),
        'parameter_info': {n: {'initial': specs[n].initial, 'min': _finite(specs[n].min), 'max': _finite(specs[n].max),
                               'unit': coefs[n].unit, 'description': coefs[n].description} for n in names},
        'parameter_correlation': [[_finite(v) for v in row] for row in corr],
        'parameter_std_note': (f'Newey-West (HAC) sandwich over the time-correlated residual (Bartlett, {lag} samples '
                               'lag); parameter_std_curvature: sigma^2 (J^T J)^-1, a lower bound'),
        'parameter_std_curvature': {n: _finite(s) for n, s in zip(names, curvature_std)},
        'model': {'coordinates': model.n, 'constraints': model.n_constraints,
                  'object': model.description.get('object', 'none'),
                  'loop_links': model.description.get('loop_links'),
                  'vi_substeps_per_sample': int(problem.substeps),
                  'feedback_kp_diag_nm_per_rad': np.diag(problem.feedback.Kp).round(3).tolist(),
                  'feedback_kd_diag_nms_per_rad': np.diag(problem.feedback.Kd).round(4).tolist()},
        'data': dict(notes),
        'bag': str(bag_path),
        'experiment': str(experiment.path),
    }
    if not notes.get('starts_at_rest', True):
        report['warnings'] = [f'the arm moves by {notes["initial_motion_rad"]:.4f} rad in the first samples: the '
                              'recording (window) should start at rest, the initial object state is assumed static']
    return report


def json_default(value):
    """numpy scalars/arrays and paths in a report -> JSON (``json.dumps(..., default=json_default)``)."""
    if hasattr(value, 'tolist'):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f'{type(value).__name__} is not JSON serializable')


def write_report(out_dir, report: dict) -> Path:
    """Write ``out_dir/report.json`` atomically (a reader never sees a partial file)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / 'report.json'
    tmp = out / '.report.json.tmp'
    tmp.write_text(json.dumps(report, indent=2, default=json_default))
    os.replace(tmp, path)
    return path
