"""Simulation-in-the-loop refinement of a planned trajectory: plan for a template, simulate, move the template
against the deviation, keep the best (model-based iterative learning control with our DER as the model).

The planner (Alg. 4) is exact only for the quasi-static grasp of a rod whose laid part stays where it was laid; the
deployment simulator shows what it does not model (the laid part dragged by the suspended one at the corners, the
free end's start, a fitted natural curvature or friction in ``rod-deploy correct``). The planner is given a
template T instead of the pattern P:

    T_0 = P,   T_{k+1} = T_best + gain * C(P - D_best),

where D_best is the simulated deployment of the best template so far (lowest Eq. 17 e_mean, directed, from the
free end) and C a Gaussian low-pass along the arc length (sigma ``smoothing_m``) of the offsets, ramped up from 0 at
the free end over ``start_taper_m`` (the template's first point stays on P's, where the free end is placed; without
the ramp a large correction there hooked the template too sharply to plan, measured on a 0.3 m rod around a corner).
The offsets (``offset``): ``'normal'`` (the default) moves the template only along P's normal, by the signed
distance of D from P there (to D's nearest point), so that a lead or lag of the rod along the curve, which moving
the template sideways cannot remove, does not move it; ``'arc_length'`` moves it by P(s) - D(s) at the same arc
lengths (Eq. 17's pairing; what ``rod-deploy correct`` used before). Measured on the paper's 7 patterns (rod #3,
medium friction, 4 simulations each, ``benchmarks/results/refine_{normal,arc}_rod3_medium.md``): mean e_mean in
our DER 0.094 cm with normal offsets, 0.109 with arc-length ones (sine 0.051 against 0.130), replayed in PyElastica
0.208 against 0.225 cm. The gain starts at ``gain`` and is halved after a worse prediction, a template the
planner refuses or a simulation that fails; the loop stops after ``simulations`` simulations or when the gain is
below ``min_gain``. What is kept is the best trajectory simulated, the unrefined one included, so the predicted
error never rises.

What it exploits (``benchmarks/error_profile.py`` on the letter A): the error arises at the bends with |kappa_bar|
near 1, where the laid rod is dragged on the table after touch-down by the suspended part (up to 13 mm); the
refined plan lays the rod off the pattern there at touch-down so that the drag brings it onto it. That depends on
the friction model, and it transfers only in part to PyElastica.

Used by ``rod-deploy plan --refine N`` (the declared rod and friction: refinement of the planner itself) and by
``rod-deploy correct --replan --simulate`` (the fitted rod: pre-compensation of fitted effects the planner does not
model). A gain seen only in our simulator may be overfitting it: ``benchmarks/deployment_table.py --refine`` with
``benchmarks/pyelastica_replay.py --traj-dir`` replays the refined trajectories in PyElastica.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from rod_deploy.deployment.metrics import arc_length, eq17_error
from rod_deploy.deployment.simulate import DeploymentError, SimulationSettings, simulate_deployment
from rod_deploy.planning.neural_controller import OutOfTrainedRange
from rod_deploy.planning.rod_description import RodDescription
from rod_deploy.planning.trajectory import PlannerSettings, PlanningError, plan_trajectory

OFFSETS = ('arc_length', 'normal')


@dataclass
class Deployment:
    """A trajectory and where its free end starts (the forward model's input)."""
    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    start_xy: tuple


@dataclass
class Candidate:
    """A trajectory with its simulated (predicted) deployment."""
    e_mean_cm: float                      # Eq. 17 e_mean (directed) of the predicted deployment against P
    deployment: Deployment
    deployed_xy: np.ndarray               # the predicted deployment, from the free end [m]
    replanned: bool = False               # False: the trajectory the loop started from
    planner_L_gb_m: float | None = None   # the L_gb the planner was given (None: the trajectory was not planned here)
    plan: object | None = None            # its PlannedTrajectory when planned here (for plots)
    result: object | None = None          # its DeploymentResult when simulated here (for plots)


@dataclass
class RefinementSettings:
    simulations: int = 4                  # simulations of templates at most (the starting trajectory's not counted)
    gain: float = 1.0                     # T_{k+1} = T_best + gain C(P - D_best); halved after a worse one
    min_gain: float = 0.2                 # stop once the gain falls below this
    smoothing_m: float = 0.02             # Gaussian low-pass of the correction along the arc length (sigma) [m]
    offset: str = 'normal'                # 'normal' (P's normal only) or 'arc_length' (Eq. 17's pairing)
    #: the correction ramps up from 0 at the free end over this arc length [m] (smoothstep; 0: a step at the first
    #: point, which stays on P's: a large correction there bends the template too sharply to plan)
    start_taper_m: float = 0.03

    def validate(self):
        if not (isinstance(self.simulations, int) and self.simulations >= 1):
            raise ValueError(f'refinement needs at least one simulation of a template, got {self.simulations!r}')
        if not (np.isfinite(self.gain) and self.gain > 0):
            raise ValueError(f'the refinement gain must be positive, got {self.gain}')
        if not (np.isfinite(self.min_gain) and 0 < self.min_gain <= self.gain):
            raise ValueError(f'min_gain must be in (0, gain], got {self.min_gain}')
        if not (np.isfinite(self.start_taper_m) and self.start_taper_m >= 0):
            raise ValueError(f'the refinement start taper must be >= 0, got {self.start_taper_m}')
        if not (np.isfinite(self.smoothing_m) and self.smoothing_m >= 0):
            raise ValueError(f'the refinement smoothing must be >= 0, got {self.smoothing_m}')
        if self.offset not in OFFSETS:
            raise ValueError(f'unknown refinement offset {self.offset!r} (one of {", ".join(OFFSETS)})')


def sample(xy, s):
    """Points of the polyline ``xy`` at arc lengths ``s`` from its first point (held at its end beyond it)."""
    sd = arc_length(xy)
    return np.column_stack([np.interp(s, sd, xy[:, k]) for k in range(2)])


class ForwardModel:
    """The deployment simulator replaying one trajectory, for rods with candidate parameters."""

    def __init__(self, deployment: Deployment, sim_settings: SimulationSettings, progress=None):
        self.deployment = deployment
        self.settings = dataclasses.replace(sim_settings, start_xy=deployment.start_xy)
        self.progress = progress
        self.count = 0
        self.result = None                # the last simulation's DeploymentResult

    def deployed(self, rod: RodDescription, label='') -> np.ndarray:
        """The deployed shape (nodes on the table from the free end) [m]; DeploymentError when the simulation fails
        or lays nothing."""
        d = self.deployment
        settings = self.settings
        if settings.friction is not None and rod.friction is not None:
            settings = dataclasses.replace(settings, friction=None)     # the rod's (fitted) friction
        cb = (lambda k, n: self.progress(label, k, n)) if self.progress else None
        try:
            result = simulate_deployment(d.t, d.position, d.quaternion, rod, settings, cb)
        except DeploymentError as e:
            raise DeploymentError(f'simulating the deployment ({label or "model"}) failed: {e}') from None
        finally:
            self.count += 1
        if len(result.deployed_xy) < 2:
            raise DeploymentError(f'the simulated deployment ({label or "model"}) laid nothing on the table')
        self.result = result
        return result.deployed_xy


def _normal_offsets(target, deployed_xy):
    """Per point of ``target`` (a resampled P): minus its signed distance along P's normal to the nearest point of
    the deployed polyline, times the normal (the correction that moves T against D's sideways deviation)."""
    tangent = np.gradient(target, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    D = np.asarray(deployed_xy, float)[:, :2]
    a, b = D[:-1], D[1:]
    ab = b - a
    ab2 = np.maximum(np.sum(ab * ab, axis=1), 1e-24)
    u = np.clip(np.einsum('pkj,kj->pk', target[:, None, :] - a[None], ab) / ab2, 0.0, 1.0)
    closest = a[None] + u[..., None] * ab[None]                        # (points, segments, 2)
    k = np.argmin(np.sum((closest - target[:, None, :]) ** 2, axis=2), axis=1)
    nearest = closest[np.arange(len(target)), k]
    signed = np.sum((nearest - target) * normal, axis=1)
    return -signed[:, None] * normal


def refine(pattern_xy, rod: RodDescription, planner_rod: RodDescription, start: Candidate,
           planner_settings: PlannerSettings, sim_settings: SimulationSettings,
           settings: RefinementSettings | None = None, progress=None, label='refined plan'):
    """Plan for templates so that the simulator with ``rod`` lays the rod on the pattern P (module doc).

    ``start``: the best trajectory so far and its simulated deployment D_0 (its template is P itself). The planner
    gets ``planner_rod`` (what it models: L_gb, the friction of the start). Returns (the best Candidate, the
    simulations run, a record: every iteration's gain, predicted e_mean and whether it was kept; CPU and wall
    time)."""
    settings = settings or RefinementSettings()
    settings.validate()
    from scipy.ndimage import gaussian_filter1d
    P = np.asarray(pattern_xy, float)[:, :2]
    t0, c0 = time.perf_counter(), time.process_time()
    length = float(arc_length(P)[-1])
    s = np.linspace(0.0, length, max(20, int(math.ceil(length / planner_settings.step_m)) + 1))
    target = sample(P, s)
    best, best_template = start, target
    gain, count, history = settings.gain, 0, []
    while count < settings.simulations and gain >= settings.min_gain:
        if settings.offset == 'normal':
            step = _normal_offsets(target, best.deployed_xy)
        else:
            step = target - sample(best.deployed_xy, s)
        if settings.smoothing_m > 0:
            step = gaussian_filter1d(step, settings.smoothing_m / (s[1] - s[0]), axis=0, mode='nearest')
        if settings.start_taper_m > 0:
            u = np.clip(s / settings.start_taper_m, 0.0, 1.0)
            step = step * (u * u * (3.0 - 2.0 * u))[:, None]
        template = best_template + gain * step
        template[0] = target[0]
        entry = {'iteration': len(history) + 1, 'gain': gain}
        history.append(entry)
        try:
            planned = plan_trajectory(template, planner_rod, planner_settings)
        except (PlanningError, OutOfTrainedRange) as e:
            entry.update(accepted=False, note=f'not plannable: {e}')
            gain *= 0.5
            continue
        dep = Deployment(planned.t, planned.position, planned.quaternion, tuple(template[0]))
        model = ForwardModel(dep, sim_settings, progress)
        try:
            d = model.deployed(rod, f'{label} {count + 1}')
        except DeploymentError as e:             # failed, or laid nothing: a worse template
            entry.update(accepted=False, note=str(e))
            gain *= 0.5
            continue
        finally:
            count += model.count
        e = eq17_error(P, d, directed=True)['e_mean_cm']
        entry.update(predicted_e_mean_cm=e, template_shift_max_mm=1e3 * float(np.max(np.linalg.norm(
            template - target, axis=1))), accepted=bool(e < best.e_mean_cm))
        if e < best.e_mean_cm:
            best = Candidate(e, dep, d, True, planner_rod.gravito_bending_length_m, planned, model.result)
            best_template = template
        else:
            gain *= 0.5
    record = {'method': f'simulation-in-the-loop refinement: plan for T_k, simulate, T_(k+1) = T_best + gain '
                        f'C(P - D_best) ({settings.offset.replace("_", " ")} offsets, smoothed over '
                        f'{1e3 * settings.smoothing_m:g} mm), gain halved after a worse prediction, best kept',
              'iterations': history, 'simulations': count, 'wall_time_s': time.perf_counter() - t0,
              'cpu_time_s': time.process_time() - c0,
              'start_predicted_e_mean_cm': start.e_mean_cm, 'predicted_e_mean_cm': best.e_mean_cm,
              'template_kept': best_template is not target}
    return best, count, record


def refine_plan(pattern_xy, rod: RodDescription, plan, planner_settings: PlannerSettings,
                sim_settings: SimulationSettings | None = None, settings: RefinementSettings | None = None,
                progress=None):
    """``plan`` (the planner's trajectory for ``pattern_xy`` with ``planner_settings``) refined with the declared
    ``rod`` in the simulator (its friction: ``sim_settings.friction``, else the rod file's, else medium). One
    simulation of the unrefined plan, then :func:`refine` with ``settings.simulations`` more at most. Returns (the
    best Candidate, record with ``simulations`` counting the first one too). Raises DeploymentError when the
    unrefined plan cannot be simulated."""
    sim_settings = sim_settings or SimulationSettings()
    settings = settings or RefinementSettings()
    settings.validate()
    c0, t0 = time.process_time(), time.perf_counter()
    P = np.asarray(pattern_xy, float)[:, :2]
    dep = Deployment(plan.t, plan.position, plan.quaternion, tuple(P[0]))
    model = ForwardModel(dep, sim_settings, progress)
    d = model.deployed(rod, 'unrefined plan')
    start = Candidate(eq17_error(P, d, directed=True)['e_mean_cm'], dep, d, False, rod.gravito_bending_length_m,
                      plan, model.result)
    best, n, record = refine(P, rod, rod, start, planner_settings, sim_settings, settings, progress)
    record.update(simulations=n + 1, cpu_time_s=time.process_time() - c0, wall_time_s=time.perf_counter() - t0)
    return best, record
