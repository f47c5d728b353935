"""`rod-deploy correct` on simulated 'measured' deployments with an undeclared natural curvature: e_mean before and
after, where 'after' is the corrected trajectory deployed by the TRUE rod (never seen by the fit).

Cases PATTERN:K0: 'line' (15 cm) and 'hook' (5 cm straight + 7 cm of radius 8 cm) with a 0.3 m rod (L_gb 3.4 cm,
mu 0.5; simulator 1 cm edges, dt 0.1 s, 0.03 m/s), 'U' (the paper's letter U) with rod #3's 0.89 m (1 cm edges,
dt 0.05 s, 0.01 m/s); nn plans with the declared (straight) rod, the planner's default start.

    .venv/bin/python benchmarks/natural_curvature_correction.py line:3 line:-3 hook:3 U:3 ...   # JSON lines
    .venv/bin/python benchmarks/natural_curvature_correction.py U:mu=0.3 U:L_gb=0.038          # the other effects
"""
import dataclasses
import json
import sys
import time

import numpy as np

from rod_deploy.deployment.correction import Deployment, correct, rod_with
from rod_deploy.deployment.metrics import eq17_error
from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment
from rod_deploy.planning.pattern_input import load_pattern
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import plan_trajectory

SHORT = rod_description_from_dict({'length': 0.3, 'radius': 0.002, 'L_gb': 0.034, 'friction': 0.5})
ROD3 = dataclasses.replace(SHORT, length_m=0.89)
_a = np.linspace(0.0, 0.07 / 0.08, 30)
HOOK = np.vstack([np.column_stack([np.linspace(0, 0.05, 11)[:-1], np.zeros(10)]),
                  np.column_stack([0.05 + 0.08 * np.sin(_a), 0.08 * (1 - np.cos(_a))])])
LINE = np.column_stack([np.linspace(0, 0.15, 31), np.zeros(31)])
FAST = SimulationSettings(edge_length_m=0.01, dt_s=0.1, max_gripper_speed_m_s=0.03, contact_tolerance_m=5e-4)
SLOW = SimulationSettings(edge_length_m=0.01, dt_s=0.05, max_gripper_speed_m_s=0.01, contact_tolerance_m=5e-4)


def case(name, k0, effect='natural_curvature_per_m'):
    """``effect``: the undeclared effect the TRUE rod has, of value ``k0`` (a natural curvature [1/m], a table
    friction, or an L_gb [m])."""
    if name == 'U':
        from pathlib import Path
        P = load_pattern(Path(__file__).resolve().parents[2] / 'shared/reference/rod_deployment/patterns/letterU.txt')
        P, rod, sim = P[:, :2], ROD3, SLOW
    else:
        P, rod, sim = {'line': LINE, 'hook': HOOK}[name], SHORT, FAST
    true = rod_with(rod, {effect: k0})
    plan = plan_trajectory(P, rod)
    observed = simulate_deployment(plan.t, plan.position, plan.quaternion, true, sim).deployed_xy
    e_before = eq17_error(P, observed, directed=True)['e_mean_cm']
    t0 = time.perf_counter()
    report, diag, rp = correct(P, rod, observed, Deployment(plan.t, plan.position, plan.quaternion, tuple(P[0])),
                               sim_settings=sim, replan_trajectory=True, simulate=True)
    wall = time.perf_counter() - t0
    e_after = e_before
    if rp is not None and rp.replanned:
        e_after = eq17_error(P, simulate_deployment(rp.t, rp.position, rp.quaternion, true, sim).deployed_xy,
                             directed=True)['e_mean_cm']
    pc = rp.precompensation if rp else None
    return dict(pattern=name, effect=effect, true_value=k0, fitted=diag.fitted, e_before_cm=e_before, e_after_true_cm=e_after,
                e_after_predicted_cm=report['error_after']['e_mean_cm'], replanned=bool(rp and rp.replanned),
                simulations=report['simulations'], wall_s=wall, precompensation=pc,
                robustness=rp.robustness if rp else None, warnings=report['warnings'])


#: the undeclared effect of a case (correction.rod_with's keys): PATTERN:K0 (natural curvature),
#: PATTERN:mu=VALUE, PATTERN:L_gb=VALUE
CASE_KEYS = {'mu': 'friction', 'L_gb': 'L_gb_m'}


if __name__ == '__main__':
    for arg in sys.argv[1:]:
        name, value = arg.split(':')
        key, _, value = value.rpartition('=')
        if key and key not in CASE_KEYS:
            sys.exit(f'unknown effect {key!r} in {arg!r} (PATTERN:K0, PATTERN:mu=VALUE or PATTERN:L_gb=VALUE)')
        print(json.dumps(case(name, float(value), CASE_KEYS.get(key, 'natural_curvature_per_m'))), flush=True)
