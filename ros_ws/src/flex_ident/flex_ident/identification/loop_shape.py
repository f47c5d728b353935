"""The identified loop's shape: the static equilibrium at the start of the recording with the identified parameters.

The measured arm joints are held at the first sample; the loop's coordinates settle under gravity, the springs (the
identified k_theta, k_phi) and the clamp welds (``mechanics.static_equilibrium``). Each branch is drawn through its
joint origins from the grasp frame to its welded end, in the arm's base frame (for markers).
"""
from __future__ import annotations

import numpy as np

from ..mechanics.assembly import build_model
from ..mechanics.experiment import load_experiment
from ..mechanics.static_equilibrium import static_equilibrium
from ..mechanics.tree_kinematics import forward_kinematics
from .measurement import load_measurements


def identified_loop_branches(bag_path, experiment_path, parameters: dict) -> list[np.ndarray]:
    """[(k, 3) points of each branch, base frame, m]; [] for an experiment without a loop."""
    experiment = load_experiment(experiment_path)
    model = build_model(experiment)
    names = list(model.coord_names)
    if 'loop_left_theta_1' not in names:
        return []
    joints = [names[i] for i in model.measured_coords]
    data, _ = load_measurements(bag_path, joints, experiment.identify.window_s)
    coef = model.coef_values()
    for name, value in parameters.items():
        try:
            coef[model.coef_index(name)] = float(value)
        except KeyError:
            continue                       # an effect the closed loop added, not a coefficient of this model
    q_guess = np.zeros(model.n)
    q_guess[model.measured_coords] = data.theta[0]
    q = static_equilibrium(model, coef, q_guess).q
    n = len(q)
    R, p, xi = np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 6))
    forward_kinematics(model.kernel(), np.ascontiguousarray(q), R, p, xi)
    branches = []
    for side in ('left', 'right'):
        thetas = [i for i, c in enumerate(names) if c.startswith(f'loop_{side}_theta_')]
        thetas.sort(key=lambda i: int(names[i].rsplit('_', 1)[1]))
        weld = next(w for w in model.welds if w.name == f'clamp_{side}')
        end = p[weld.coord] + R[weld.coord] @ weld.offset[:3, 3]
        branches.append(np.vstack([p[thetas], end]))
    return branches
