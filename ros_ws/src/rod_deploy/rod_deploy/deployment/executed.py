"""A deployment along the gripper path an arm actually executed: the rod simulation, Eq. 17, and the files saved.

Input: the prescribed pattern (table frame, metres), the executed gripper path (one pose per planned pose, e.g. the
forward kinematics of the measured joint states, ``robot_bridge.kinematics.execution``), how many of its first poses
are the planner's lead-in (the straight line from the hanging pose: the free end is held until its end), the rod
and the simulation settings. The rod is simulated along the executed path (``simulate.simulate_deployment``), the
deployed shape scored against the pattern (``metrics.eq17_error``), and everything written to ``out_dir``:

  pattern.txt                  the prescribed pattern (x y z per line, CONTRACTS.md section 4)
  planned_trajectory.csv       the planned gripper trajectory (t,x,y,z,qx,qy,qz,qw), if given
  executed_trajectory.csv      the executed gripper path (same format)
  deployed.csv                 the deployed shape (x,y)
  deployment.png               prescribed vs deployed, with the gripper path (top view)
  deployment.json              the summary returned
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from rod_deploy.perception.path_io import write_pattern_file
from rod_deploy.planning.rod_description import RodDescription
from rod_deploy.planning.trajectory_io import write_trajectory_csv

from .metrics import eq17_error, write_deployed_csv
from .plots import plot_deployment
from .simulate import DeploymentError, DeploymentResult, SimulationSettings, simulate_deployment


def deploy_along_executed_path(pattern_xy, t_s, position_m, quaternion_xyzw, n_lead_in: int, rod: RodDescription,
                               settings: SimulationSettings, out_dir, planned=None, extra: dict | None = None,
                               progress=None) -> tuple[dict, DeploymentResult]:
    """Simulate, score, save (see the module docstring). ``planned``: optional (t, position, quaternion) of the plan,
    saved beside the executed path. ``extra``: more keys for deployment.json (timings, tracking errors, ...).
    Returns (summary, the simulation result); raises DeploymentError when the rod cannot be simulated or nothing
    was laid on the table."""
    pattern_xy = np.asarray(pattern_xy, float)[:, :2]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    result = simulate_deployment(t_s, position_m, quaternion_xyzw, rod, settings, progress=progress,
                                 n_lead_in=n_lead_in)
    wall_s = time.perf_counter() - t0
    if len(result.deployed_xy) < 2:
        raise DeploymentError(f'{len(result.deployed_xy)} rod node(s) ended on the table: nothing to score')
    error = eq17_error(pattern_xy, result.deployed_xy)
    files = {'pattern': out / 'pattern.txt', 'executed_trajectory': out / 'executed_trajectory.csv',
             'deployed': out / 'deployed.csv', 'plot': out / 'deployment.png', 'json': out / 'deployment.json'}
    write_pattern_file(files['pattern'], pattern_xy)
    if planned is not None:
        files['planned_trajectory'] = out / 'planned_trajectory.csv'
        write_trajectory_csv(files['planned_trajectory'], *planned)
    write_trajectory_csv(files['executed_trajectory'], t_s, position_m, quaternion_xyzw)
    write_deployed_csv(files['deployed'], result.deployed_xy)
    plot_deployment(files['plot'], result, pattern_xy, title='deployed along the executed gripper path')
    summary = {**error, 'rod': {'length_m': rod.length_m, 'radius_m': rod.radius_m,
                                'L_gb_m': rod.gravito_bending_length_m, 'friction': result.friction},
               'simulation': {'edge_length_m': settings.edge_length_m, 'dt_s': settings.dt_s,
                              'max_gripper_speed_m_s': settings.max_gripper_speed_m_s, 'steps': result.steps,
                              'newton_iterations': result.newton_iterations, 'wall_time_s': round(wall_s, 3)},
               'executed_poses': int(len(t_s)), 'lead_in_poses': int(n_lead_in),
               **(extra or {}), 'files': {k: str(v) for k, v in files.items()}}
    files['json'].write_text(json.dumps(summary, indent=2, default=float) + '\n')
    return summary, result
