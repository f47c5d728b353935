"""How fast the planned curvature may change along the pattern: the laid rod cannot take a sudden change of moment.

Why the gripper jumped (issue #10, ``benchmarks/grasp_jump.py``): the optimal grasp is a smooth function of the
node's curvature, with no change of branch (the network agrees with the numeric solver there to 0.02 L_gb), but a
steep one - at ls_bar = 25 the gripper's lateral offset moves by 5-6 L_gb per unit of kappa_bar, 17-20 cm for rod
#3. A pattern whose curvature changes by about one unit of kappa_bar within one 5 mm node (the 10 cm hook's straight
stem running into its 1.6 cm curl, the digit 2's lower corner) therefore moves the gripper 11-17 cm per node, along a
straight chord up to 4.8 cm off the path of the optimal grasps in between.

The jump is not what drags the laid rod: the same trajectories deploy to 0.29-0.37 cm on a table with friction 2-5
instead of 1.2-9.4 cm at 0.5, and 1 mm nodes (the gripper on the optimal grasps all along, steps of 2.7 cm) leave the
digit 2 as it was (1.86 cm against 1.81). The optimal grasp at a node imposes the pattern's bending moment EI kappa
there; the rod laid just before it holds its own, and the difference is taken by friction over a length of laid rod
that grows with the jump (a sudden kappa_bar of 2.5 after a 30 cm straight lead drags the last 11 cm of the lead into
a loop at friction 0.5). The planner therefore asks the grasp solver for a curvature that changes at most ``max_rate``
per L_gb of pattern: :func:`limit_curvature_rate` spreads a faster change over the neighbouring nodes, conservatively
(the integral of kappa, the pattern's turning, is kept, so the heading after the change is the pattern's) and only
where the limit is exceeded (a curvature that changes slower is untouched). The contact point and the tangent stay on
the pattern; the grasp moves at most about 1 cm per node in the pattern's frame (the rate times dq/dkappa_bar), the
gripper a few centimetres in the table's (it also orbits the contact point as the tangent turns). Measured at friction
0.5 (rod #3, e_mean): digit 2 1.81 -> 0.60 cm, tight wave 1.20 -> 0.79, letter A 0.84 -> 0.42; the limit's default
scales with sqrt(friction) (:func:`default_max_rate`). A ramp may not bend the friction-limited start more than
friction holds there (the planner caps it, ``trajectory.plan_trajectory``).
"""
from __future__ import annotations

import numpy as np

#: the limit on |d kappa_bar / d(s / L_gb)| of the planned curvature at table friction 0.5 (benchmarks/grasp_jump.py:
#: rod #3, 1 -> 0.5 -> 0.35 -> 0.25 -> 0.125 per L_gb; 0.35 the largest gain with none of the paper's 7 worse)
DEFAULT_MAX_RATE = 0.35
#: the friction DEFAULT_MAX_RATE was measured at
DEFAULT_RATE_FRICTION = 0.5


def default_max_rate(friction):
    """The default limit at table friction ``friction``: DEFAULT_MAX_RATE sqrt(friction / 0.5). Friction over a
    stretch l of laid rod holds a change of kappa_bar of about mu (l / L_gb)^2 / 8 (achievable_start.py's bound), so
    a change d kappa_bar needs a ramp of L_gb sqrt(8 d kappa_bar / mu): its slope scales with sqrt(mu). Measured at
    0.5 (the paper's medium) and, for the hook, at 5 (benchmarks/grasp_jump.py)."""
    return DEFAULT_MAX_RATE * float(np.sqrt(friction / DEFAULT_RATE_FRICTION))


def limit_curvature_rate(kappa_bar, step_bar, max_rate, max_iterations=20000):
    """kappa_bar (m,) with |kappa_bar[i+1] - kappa_bar[i]| <= max_rate * step_bar at every node pair.

    Conservative diffusion on the violating node pairs only: each pair that changes by more than the limit passes a
    share of its excess to the other node; the sum of kappa_bar (the total turning) is unchanged and a curvature that
    changes within the limit everywhere is returned unchanged. ``step_bar``: the node spacing over L_gb."""
    k = np.array(kappa_bar, float, copy=True)
    if not np.isfinite(max_rate):
        return k
    if not (max_rate > 0 and step_bar > 0):
        raise ValueError(f'max_rate and step_bar must be positive, got {max_rate}, {step_bar}')
    limit = max_rate * step_bar
    tol = 1e-2 * limit
    for _ in range(max_iterations):
        d = np.diff(k)
        excess = np.sign(d) * np.maximum(np.abs(d) - limit, 0.0)
        if np.abs(excess).max(initial=0.0) <= tol:
            return k
        # 1/3 of the excess each way: a node between two violating pairs still moves less than either asks
        k[:-1] += excess / 3.0
        k[1:] -= excess / 3.0
    raise RuntimeError('the curvature rate limit did not converge')   # pragma: no cover (a bounded diffusion)
