"""The deployment's closed loop: explain a deployed shape the planner did not predict, fit it, replan.

The forward model is our DER deployment simulator (``simulate``) replaying the trajectory that produced the deployment
(``--traj``, or the planner's trajectory for the declared rod). The residual compared is the observed deployed shape
minus the simulated one, both read at the same ``n_points`` arc lengths from the free end up to the shorter of the
pattern and the observed curve (a model curve shorter than that is held at its end, so shortening shows). The
simulator with the declared rod already carries the planner's own error; what is left is what the declared rod
does not explain.

Candidate effects (:data:`EFFECTS`), one parameter each: a natural (rest) curvature of the rod in the table's plane
(``natural_curvature_per_m``, 0 declared), a wrong gravito-bending length (``L_gb_m``: a stiffer or softer rod lags or
leads along the pattern and turns its bends with offsets that scale with L_gb), and a lower Coulomb friction
(``friction``: the laid part creeps towards the gripper). Each costs one simulation with the parameter perturbed
(finite-difference sensitivities J of the residual); the natural curvature two, one per sign, each a candidate
fitted on its own side only (the laid rod rolls differently for the two signs, so the response is not odd: with the
positive step alone a rod with -3 /m on a left turn was fitted as a wrong L_gb, and on the letter U as +2.75 /m); a
sensitivity that cannot be simulated (the rod curls off the table) is retried at half the step, then dropped with a
warning. Effects are added by forward selection, each scored by the
Bayesian information criterion

    BIC_k = n ln((RSS_k + n sigma_floor^2) / n) + k ln n,   n = 2 n_points,

where ``sigma_floor`` (default 0.5 mm) is the accuracy below which shapes are not told apart (perception, simulation
settings): a deployment matching the declared model within it leaves nothing to explain, and no further effect is
added once the residual is within it. The next effect is the one
whose linear least-squares fit (jointly with those already added) lowers BIC most, by more than ``bic_threshold``
(10: strong evidence), and whose parameters fitted on the first ``1 - holdout_fraction`` of the curve also lower
the residual on the held-out rest; it is added only if a confirming simulation with the fitted parameters lowers
the residual sum of squares by at least ``min_rss_drop`` with the same strong BIC evidence (a second step with
Broyden-updated sensitivities is tried when the first falls short: the response is not linear over the range of
real errors; at most ``max_confirmations`` confirming simulations in all).

Replanning (:func:`replan`, only when an effect was added): the planner takes the fitted L_gb directly. The
replanned trajectory is simulated with the fitted rod and kept only if it is predicted to deploy better than the
original one; if not, and L_gb was fitted, the planner's L_gb on the other side of the declared one is tried (the
planner has its own bias in L_gb on short rods, which the fitted model shows). A fitted natural curvature or lower
friction is not in the planner's model; with ``simulate`` it is pre-compensated with the FITTED simulator in the loop
(``rod_deploy.deployment.refinement.refine``, the code path of ``rod-deploy plan --refine``): plan for a template T
(T_0 = the pattern P, with the best trajectory so far), simulate it with the fitted rod (deployment D),
T_{k+1} = T_best + gain (P - D_best) (``RefinementSettings``' defaults), at most 4 simulations, the trajectory
predicted best kept (the original included); the iteration is erratic
(benchmarks/results/natural_curvature_correction.md). Without ``simulate`` nothing is pre-compensated. A replan
chosen this way is then simulated with rods beside the fitted one (:func:`robustness`: each fitted parameter moved
both ways by its :meth:`Effect.tolerance`) and kept only if every one of them is predicted
to lay it better than the fitted model predicts the original: a replan near an instability (a short rod's free end
dragged off) can be predicted well by the fitted rod alone and laid far off by the real one.

Why not plan with an effective curvature kappa_pattern - kappa0: the laid rod's material frame is not fixed
(``benchmarks/natural_curvature_frame.py``): a clean rod lies with d1 up (the frame the simulator's
``NATURAL_CURVATURE_SIGN`` assumes) for every direction, turning sense (the network's mirroring) and start, but a
rod with a natural curvature rolls about its axis as it is laid, by 18-26 degrees where the pattern is straight or
turns with kappa0, and by about 80 degrees where it turns against it (its rest curvature then bends out of the
table's plane). The in-plane effect is therefore neither kappa0 nor linear in it (on a 15 cm line a 0.3 m rod with
3 /m turns by about 1 /m more), and planning a line as an arc of curvature -kappa0 (or +kappa0) laid it 10x worse
than ignoring kappa0 (e_mean 1.31 / 1.04 cm against 0.11 cm), the opposite sign less badly. The simulator models the
roll; the pre-compensation inherits it.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from rod_deploy.deployment.metrics import arc_length, eq17_error
from rod_deploy.deployment.refinement import (Candidate, Deployment, ForwardModel, RefinementSettings, refine,
                                              sample)
from rod_deploy.deployment.simulate import DeploymentError, SimulationSettings
from rod_deploy.planning.rod_description import RodDescription
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory


class CorrectionError(ValueError):
    """Inputs the closed loop cannot use (clear message, no partial report)."""


@dataclass(frozen=True)
class Effect:
    key: str              # parameter name in the report
    name: str             # what it is, for people
    unit: str
    side: float = 1.0     # natural curvature: the sign of the finite-difference step and of the fitted value

    def nominal(self, rod: RodDescription) -> float:
        if self.key == 'natural_curvature_per_m':
            return rod.natural_curvature_per_m
        if self.key == 'L_gb_m':
            return rod.gravito_bending_length_m
        return rod.friction

    def step(self, rod: RodDescription) -> float:
        """Finite-difference step of the sensitivity (a clearly visible but moderate change)."""
        if self.key == 'natural_curvature_per_m':
            return self.side * 0.2 / rod.gravito_bending_length_m    # a bend of radius 5 L_gb, on its side
        if self.key == 'L_gb_m':
            return 0.15 * rod.gravito_bending_length_m
        return -0.5 * rod.friction                             # towards too little friction

    def tolerance(self, rod: RodDescription) -> float:
        """How far from the fitted value the true one may lie (:func:`robustness`): about what the diagnosis was
        measured to miss by, with a margin (the letter U on rod #3: natural curvature fitted 0.44-0.48 /m off, 0.10
        /m at +5; L_gb 0.1-2 % off; friction 7 % off)."""
        if self.key == 'natural_curvature_per_m':
            return 0.02 / rod.gravito_bending_length_m     # 0.59 /m on rod #3
        if self.key == 'L_gb_m':
            return 0.03 * rod.gravito_bending_length_m
        return 0.1 * rod.friction

    def clip(self, value: float, rod: RodDescription) -> float:
        if self.key == 'L_gb_m':
            return float(np.clip(value, 0.3 * rod.gravito_bending_length_m, 3.0 * rod.gravito_bending_length_m))
        if self.key == 'friction':                   # the effect is too little friction
            return float(np.clip(value, 0.02 * rod.friction, rod.friction))
        nominal = self.nominal(rod)                  # natural curvature: on the side its sensitivity was taken
        return float(nominal + self.side * max(self.side * (value - nominal), 0.0))


EFFECTS = {
    'natural_curvature': Effect('natural_curvature_per_m', 'natural curvature of the rod (not declared)', '1/m'),
    'L_gb': Effect('L_gb_m', 'gravito-bending length L_gb differs from the declared one (stiffer/softer rod)', 'm'),
    'friction': Effect('friction', 'lower friction with the table than declared (slip, creep)', '1'),
}


def rod_with(rod: RodDescription, values: dict) -> RodDescription:
    """The rod with effect parameters {key: value} (keys of :data:`EFFECTS`' ``key``)."""
    changes = {}
    if 'natural_curvature_per_m' in values:
        changes['natural_curvature_per_m'] = float(values['natural_curvature_per_m'])
    if 'L_gb_m' in values:
        changes['gravito_bending_length_m'] = float(values['L_gb_m'])
        if rod.youngs_modulus_pa and rod.density_kg_m3:      # the simulator would take E and rho: drop them
            changes['youngs_modulus_pa'] = None
    if 'friction' in values:
        changes['friction'] = float(values['friction'])
    return dataclasses.replace(rod, **changes)


@dataclass
class CorrectionSettings:
    effects: tuple = ('natural_curvature', 'L_gb', 'friction')
    n_points: int = 50                     # arc-length samples of the residual (Eq. 17's N)
    noise_floor_m: float = 0.0005          # sigma_floor: shapes closer than this are not told apart
    bic_threshold: float = 10.0            # strong evidence
    holdout_fraction: float = 1.0 / 3.0    # the end of the curve, never fitted, must improve too
    min_rss_drop: float = 0.2              # the confirming simulation must lower RSS by this fraction
    max_confirmations: int = 4             # simulations spent confirming linearised candidates

    def validate(self):
        unknown = [e for e in self.effects if e not in EFFECTS]
        if unknown or not self.effects:
            raise CorrectionError(f'unknown effect(s) {", ".join(unknown) or "(none given)"} '
                                  f'(known: {", ".join(EFFECTS)})')
        if self.n_points < 10:
            raise CorrectionError(f'n_points must be at least 10, got {self.n_points}')
        if not (np.isfinite(self.noise_floor_m) and self.noise_floor_m > 0):
            raise CorrectionError(f'the noise floor must be positive, got {self.noise_floor_m}')
        if not 0.0 < self.holdout_fraction < 0.8:
            raise CorrectionError(f'holdout_fraction must be in (0, 0.8), got {self.holdout_fraction}')


@dataclass
class Diagnosis:
    effects_added: list
    fitted: dict                    # {parameter key: value} of the added effects
    rod: RodDescription             # the declared rod with the added effects
    observed_xy: np.ndarray
    nominal_xy: np.ndarray          # the declared rod's simulated deployment
    fitted_xy: np.ndarray           # the fitted rod's simulated deployment (= nominal if nothing added)
    rms_before_m: float             # residual RMS, observed vs the declared model
    rms_after_m: float              # observed vs the fitted model
    candidates: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    simulations: int = 0


def orient_observed(pattern_xy, observed_xy):
    """The observed curve from the end nearer the pattern's first point (a perceived path has no direction)."""
    observed_xy = np.asarray(observed_xy, float)
    p0 = np.asarray(pattern_xy, float)[0]
    if np.linalg.norm(observed_xy[-1] - p0) < np.linalg.norm(observed_xy[0] - p0):
        return observed_xy[::-1].copy()
    return observed_xy


def _bic(rss, n, k, floor2):
    return n * math.log((rss + n * floor2) / n) + k * math.log(n)


def _lstsq(J, r):
    theta, *_ = np.linalg.lstsq(J, r, rcond=None)
    return theta, float(np.sum((r - J @ theta) ** 2))


def diagnose(pattern_xy, rod: RodDescription, deployment: Deployment, observed_xy, sim_settings: SimulationSettings,
             settings: CorrectionSettings | None = None, progress=None) -> Diagnosis:
    """Which candidate effects explain observed - simulated(declared rod); fitted, or none (see module doc)."""
    settings = settings or CorrectionSettings()
    settings.validate()
    if rod.friction is None and 'friction' in settings.effects:
        rod = dataclasses.replace(rod, friction=sim_settings.friction if sim_settings.friction is not None else 0.5)
    observed = orient_observed(pattern_xy, observed_xy)
    length = min(float(arc_length(np.asarray(pattern_xy, float))[-1]), float(arc_length(observed)[-1]))
    if length <= 0:
        raise CorrectionError('the observed deployed shape has zero length')
    s = np.linspace(0.0, length, settings.n_points)
    obs = sample(observed, s)
    model = ForwardModel(deployment, sim_settings, progress)
    nominal_xy = model.deployed(rod, 'declared rod')
    r0 = (obs - sample(nominal_xy, s)).ravel()
    n = r0.size
    floor2 = settings.noise_floor_m ** 2
    rss0 = float(r0 @ r0)
    out = Diagnosis([], {}, rod, observed, nominal_xy, nominal_xy, math.sqrt(rss0 / n), math.sqrt(rss0 / n))
    if rss0 <= n * floor2:
        out.simulations = model.count
        out.candidates.append({'effects': [], 'note': f'the residual ({1e3 * math.sqrt(rss0 / n):.3f} mm RMS) is '
                                                      f'within the noise floor ({1e3 * settings.noise_floor_m:g} mm)'})
        return out
    # -- sensitivities: one simulation per candidate effect
    # a natural curvature is not odd in its sign (the laid rod rolls one way or the other, see the module doc):
    # one sensitivity per sign, each fitted on its own side only
    effects = [v for e in settings.effects for v in (
        (EFFECTS[e], dataclasses.replace(EFFECTS[e], side=-1.0)) if e == 'natural_curvature' else (EFFECTS[e],))]
    if any(e.step(rod) == 0 for e in effects):                # friction declared 0: it cannot be lower
        out.warnings.append('the declared friction is 0: too little friction is not a candidate')
        effects = [e for e in effects if e.step(rod) != 0]
    J = np.zeros((n, len(effects)))
    usable = []
    for j, e in enumerate(effects):
        for h in (e.step(rod), 0.5 * e.step(rod)):      # a rod curled off the table: a smaller step
            try:
                d = model.deployed(rod_with(rod, {e.key: e.nominal(rod) + h}), f'{e.key} + {h:.3g}')
            except DeploymentError as err:
                failed = str(err)
                continue
            J[:, j] = (sample(d, s) - sample(nominal_xy, s)).ravel() / h
            usable.append(j)
            break
        else:
            out.warnings.append(f'{e.key} {"< 0" if e.side < 0 else ""} is not a candidate: its sensitivity could not '
                                f'be simulated ({failed})')
    effects, J = [effects[j] for j in usable], J[:, usable]
    # -- forward selection: the effect whose linearised fit lowers BIC most (with the held-out check) is confirmed
    #    by a simulation; once confirmed, the next effect must lower the confirmed BIC further, and so on
    n_fit = int(round((1.0 - settings.holdout_fraction) * settings.n_points))
    fit_rows = np.zeros((settings.n_points, 2), bool)
    fit_rows[:n_fit] = True
    fit_rows = fit_rows.ravel()
    selected, x_sel = [], np.zeros(0)               # effect indices and their fitted values
    r_cur, rss_cur, bic_cur, xy_cur, rod_cur = r0, rss0, _bic(rss0, n, 0, floor2), nominal_xy, rod
    rejected = set()
    budget = settings.max_confirmations
    stage_errors = []
    while budget > 0 and rss_cur > n * floor2:          # within the noise floor: nothing left to explain
        ranked = []
        for j in range(len(effects)):
            if j in selected or j in rejected or effects[j].key in [effects[k].key for k in selected]:
                continue
            cols = selected + [j]
            Js = J[:, cols]
            step, rss = _lstsq(Js, r_cur)
            bic = _bic(rss, n, len(cols), floor2)
            st_fit, _ = _lstsq(Js[fit_rows], r_cur[fit_rows])
            rh = r_cur[~fit_rows]
            held_before, held_after = float(rh @ rh), float(np.sum((rh - Js[~fit_rows] @ st_fit) ** 2))
            cand = {'effects': [effects[k].key + (' (< 0)' if effects[k].side < 0 else '') for k in cols],
                    'rss_drop': 1.0 - rss / rss_cur,
                    'bic_change': bic - bic_cur, 'holdout_rms_before_m': math.sqrt(held_before / rh.size),
                    'holdout_rms_after_m': math.sqrt(held_after / rh.size)}
            out.candidates.append(cand)
            if bic - bic_cur < -settings.bic_threshold and held_after < held_before:
                ranked.append((bic, j, step, cand))
        if not ranked:
            break
        ranked.sort(key=lambda c: c[0])
        accepted = False
        for _, j, step, cand in ranked:
            if budget <= 0:
                break
            cols = selected + [j]
            Js = J[:, cols].copy()
            x0 = np.concatenate([x_sel, [effects[j].nominal(rod)]])
            clip = lambda v: np.array([effects[k].clip(x, rod) for k, x in zip(cols, v)])  # noqa: E731
            x_prev, r_prev, x = x0, r_cur, clip(x0 + step)
            tries = []
            for attempt in range(2):
                if budget <= 0:
                    break
                values = {effects[k].key: float(v) for k, v in zip(cols, x)}
                trial_rod = rod_with(rod, values)
                try:
                    d = model.deployed(trial_rod, 'fitted ' + ', '.join(values) + (' (2nd step)' if attempt else ''))
                except DeploymentError:                 # failed or laid nothing: not confirmed
                    budget -= 1
                    break
                budget -= 1
                r = (obs - sample(d, s)).ravel()
                tries.append((float(r @ r), x.copy(), r, trial_rod, d))
                if r @ r <= (1.0 - settings.min_rss_drop) * rss_cur:
                    break
                dx = x - x_prev
                if np.any(dx):
                    Js += np.outer((r_prev - r) - Js @ dx, dx) / float(dx @ dx)       # Broyden
                more, _ = _lstsq(Js, r)
                x_prev, r_prev, x = x, r, clip(x + more)
            if not tries:
                break
            rss, x_best, r_best, rod_best, d_best = min(tries, key=lambda t_: t_[0])
            bic = _bic(rss, n, len(cols), floor2)
            cand['confirmed_rss_drop'] = 1.0 - rss / rss_cur
            cand['confirmed_bic_change'] = bic - bic_cur
            if rss <= (1.0 - settings.min_rss_drop) * rss_cur and bic - bic_cur < -settings.bic_threshold:
                stage_errors.append((j, cand, rss_cur, rss, xy_cur, d_best))
                selected, x_sel = cols, x_best
                r_cur, rss_cur, bic_cur, xy_cur, rod_cur = r_best, rss, bic, d_best, rod_best
                accepted = True
                break
            rejected.add(j)
        if not accepted:
            break
    out.simulations = model.count
    if not selected:
        tried = [', '.join(c['effects']) for c in out.candidates if 'confirmed_rss_drop' in c]
        if tried:
            out.warnings.append(f'the linearised fit suggested {" or ".join(tried)}, but simulations with the fitted '
                                f'parameters do not lower the residual by {100 * settings.min_rss_drop:.0f} % with '
                                f'strong evidence: nothing added')
        else:
            out.warnings.append(f'the deployed shape differs from the declared model by {1e3 * out.rms_before_m:.2f} '
                                f'mm RMS, but no candidate effect explains it (BIC with a '
                                f'{1e3 * settings.noise_floor_m:g} mm noise floor, held-out end of the curve)')
        return out
    values = {effects[k].key: float(v) for k, v in zip(selected, x_sel)}
    for j, cand, rss_b, rss_a, xy_b, xy_a in stage_errors:
        e = effects[j]
        out.effects_added.append({
            'name': e.name, 'key': e.key,
            'parameters': {e.key: values[e.key], f'{e.key}_declared': e.nominal(rod)},
            'evidence': (f'residual (observed - simulated) {1e3 * math.sqrt(rss_b / n):.2f} -> '
                         f'{1e3 * math.sqrt(rss_a / n):.2f} mm RMS when added (fitted with '
                         f'{", ".join(cand["effects"])}; confirmed by simulation, BIC change '
                         f'{cand["confirmed_bic_change"]:.1f}, threshold -{settings.bic_threshold:g}, noise floor '
                         f'{1e3 * settings.noise_floor_m:g} mm); linearised: residual sum of squares '
                         f'{100 * cand["rss_drop"]:.1f} % lower, BIC change {cand["bic_change"]:.1f}; held-out last '
                         f'{100 * settings.holdout_fraction:.0f} % of the curve '
                         f'{1e3 * cand["holdout_rms_before_m"]:.2f} -> {1e3 * cand["holdout_rms_after_m"]:.2f} mm'),
            'error_before': {'residual_rms_mm': 1e3 * math.sqrt(rss_b / n),
                             'model_e_mean_cm': eq17_error(pattern_xy, xy_b, directed=True)['e_mean_cm']},
            'error_after': {'residual_rms_mm': 1e3 * math.sqrt(rss_a / n),
                            'model_e_mean_cm': eq17_error(pattern_xy, xy_a, directed=True)['e_mean_cm']}})
    fitted_rod, fitted_xy, rss1 = rod_cur, xy_cur, rss_cur
    out.fitted = values
    out.rod = fitted_rod
    out.fitted_xy = fitted_xy
    out.rms_after_m = math.sqrt(rss1 / n)
    return out


@dataclass
class Replan:
    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    replanned: bool                       # False: the original plan is kept (the replanned one predicted no better)
    predicted_xy: np.ndarray | None       # the fitted model's deployment of it (None if not simulated)
    predicted_e_mean_cm: float | None
    original_predicted_e_mean_cm: float | None
    simulations: int
    planner_L_gb_m: float | None          # the L_gb the planner was given (None: the original trajectory kept)
    #: pre-compensation for fitted effects the planner does not model (None: not run): iterations, kept one
    precompensation: dict | None = None
    #: the chosen replan's predictions for rods beside the fitted one (:func:`robustness`; None: not checked)
    robustness: dict | None = None


ROBUSTNESS_NOTE = ('each fitted parameter moved both ways by its tolerance (Effect.tolerance: L_gb 3 %, natural '
                   'curvature 0.02 / L_gb, friction 10 %)')


def robustness(pattern_xy, candidate: Candidate, diagnosis: Diagnosis, sim_settings: SimulationSettings,
               e_original_cm: float, progress=None) -> dict:
    """The replanned ``candidate`` simulated with rods beside the fitted one (each fitted parameter moved both ways by
    :meth:`Effect.tolerance`); it is robust when every one of them is predicted to lay it better than the fitted
    model predicts the original (``e_original_cm``). A simulation that fails counts as not robust (its row says why,
    ``worst_e_mean_cm`` None). Why: a replan near an instability can be predicted well by the fitted rod alone and
    laid far off by the real one (the short-rod test with a wrong L_gb, simulated from below the hanging pose: the
    chosen replan, predicted 0.57 cm, laid 3.0-4.3 cm off by rods 2-3 % off the fitted L_gb, or not simulated)."""
    model = ForwardModel(candidate.deployment, sim_settings, progress)
    effects = {e.key: e for e in EFFECTS.values()}
    rows = []
    for key, value in diagnosis.fitted.items():
        delta = effects[key].tolerance(diagnosis.rod)
        for sign in (-1.0, 1.0):
            v = value + sign * delta
            row = {'parameter': key, 'value': v}
            try:
                d = model.deployed(rod_with(diagnosis.rod, {key: v}), f'corrected plan, {key} {v:.4g}')
                row['predicted_e_mean_cm'] = eq17_error(pattern_xy, d, directed=True)['e_mean_cm']
            except DeploymentError as e:
                row['failed'] = str(e)[:200]
            rows.append(row)
    failed = any('failed' in r for r in rows)
    worst = None if failed else max([r['predicted_e_mean_cm'] for r in rows], default=candidate.e_mean_cm)
    return {'neighbours_are': ROBUSTNESS_NOTE, 'neighbours': rows, 'worst_e_mean_cm': worst,
            'robust': bool(worst is not None and worst < e_original_cm), 'simulations': model.count}


#: fitted parameters the planner takes directly; the others are pre-compensated with the fitted simulator
PLANNER_MODELS = ('L_gb_m',)


def replan(pattern_xy, diagnosis: Diagnosis, deployment: Deployment, planner_settings: PlannerSettings,
           sim_settings: SimulationSettings, simulate=True, progress=None,
           precompensation: RefinementSettings | None = None) -> Replan:
    """The trajectory planned with the fitted rod; with ``simulate``, its deployment predicted by the fitted
    simulator (module doc). When that is predicted no better than the original trajectory and L_gb was fitted,
    the planner's L_gb is also tried on the other side of the declared one (declared^2 / fitted: the planner's own
    bias in L_gb, seen through the fitted model); the trajectory predicted best is kept, the original included.
    Fitted effects the planner does not model (natural curvature, friction) are then pre-compensated with the
    fitted simulator in the loop (``refinement.refine`` with the fitted rod; only with ``simulate``)."""
    pattern_xy = np.asarray(pattern_xy, float)
    rod = diagnosis.rod
    unmodelled = [k for k in diagnosis.fitted if k not in PLANNER_MODELS]
    e_old = eq17_error(pattern_xy, diagnosis.fitted_xy, directed=True)['e_mean_cm']
    original = best = Candidate(e_old, deployment, diagnosis.fitted_xy)
    count = 0
    if 'L_gb_m' in diagnosis.fitted:
        planned = plan_trajectory(pattern_xy, rod, planner_settings)
        if not simulate:
            return Replan(planned.t, planned.position, planned.quaternion, True, None, None, None, 0,
                          rod.gravito_bending_length_m)
        declared = next(e['parameters']['L_gb_m_declared'] for e in diagnosis.effects_added
                        if e['key'] == 'L_gb_m')
        knobs = [rod.gravito_bending_length_m, declared ** 2 / rod.gravito_bending_length_m]
        for k, planner_lgb in enumerate(knobs):
            if k > 0 and best.replanned:
                break                                # the fitted rod's plan already does better than the original
            if k > 0:
                planned = plan_trajectory(pattern_xy, rod_with(rod, {'L_gb_m': planner_lgb}), planner_settings)
            model = ForwardModel(Deployment(planned.t, planned.position, planned.quaternion, tuple(pattern_xy[0])),
                                 sim_settings, progress)
            d = model.deployed(rod, f'corrected plan (planner L_gb {1e3 * planner_lgb:.1f} mm), fitted rod')
            count += 1
            e = eq17_error(pattern_xy, d, directed=True)['e_mean_cm']
            if e < best.e_mean_cm:
                best = Candidate(e, model.deployment, d, True, planner_lgb, planned)
    record = None
    if unmodelled and simulate:
        planner_rod = rod if best.planner_L_gb_m is None else rod_with(rod, {'L_gb_m': best.planner_L_gb_m})
        best, n, record = refine(pattern_xy, rod, planner_rod, best, planner_settings, sim_settings,
                                 precompensation, progress, label='pre-compensated plan, fitted rod:')
        count += n
    check = None
    if best.replanned and simulate:
        # a replan predicted better by the fitted rod alone may sit near an instability that a rod a little off the
        # fitted one falls into: it is kept only if the rods beside the fitted one lay it better too
        check = robustness(pattern_xy, best, diagnosis, sim_settings, e_old, progress)
        count += check['simulations']
        if not check['robust']:
            best = original
    dep = best.deployment
    return Replan(dep.t, dep.position, dep.quaternion, best.replanned, best.deployed_xy, best.e_mean_cm, e_old,
                  count, best.planner_L_gb_m, record, check)


def correct(pattern_xy, rod: RodDescription, observed_xy, deployment: Deployment | None = None,
            planner_settings: PlannerSettings | None = None, sim_settings: SimulationSettings | None = None,
            settings: CorrectionSettings | None = None, replan_trajectory=True, simulate=True, progress=None,
            precompensation: RefinementSettings | None = None):
    """diagnose + replan; returns (report dict, Diagnosis, Replan or None)."""
    t0 = time.perf_counter()
    settings = settings or CorrectionSettings()
    planner_settings = planner_settings or PlannerSettings()
    sim_settings = sim_settings or SimulationSettings()
    pattern_xy = np.asarray(pattern_xy, float)[:, :2]
    source = 'given'
    if deployment is None:
        plan = plan_trajectory(pattern_xy, rod, planner_settings)
        deployment = Deployment(plan.t, plan.position, plan.quaternion, tuple(pattern_xy[0]))
        source = f'planned ({planner_settings.method}) with the declared rod'
    diag = diagnose(pattern_xy, rod, deployment, observed_xy, sim_settings, settings, progress)
    before = eq17_error(pattern_xy, diag.observed_xy, directed=True)
    report = {
        'parameters': {'L_gb_m': diag.rod.gravito_bending_length_m,
                       'natural_curvature_per_m': diag.rod.natural_curvature_per_m,
                       'friction': diag.rod.friction},
        'declared': {'L_gb_m': rod.gravito_bending_length_m, 'natural_curvature_per_m': rod.natural_curvature_per_m,
                     'friction': rod.friction},
        'effects_added': diag.effects_added,
        'error_before': {'e_mean_cm': before['e_mean_cm'], 'sigma_cm': before['sigma_cm'],
                         'coverage': before['coverage'], 'residual_rms_mm': 1e3 * diag.rms_before_m},
        'error_after': None,
        'warnings': list(diag.warnings),
        'candidates': diag.candidates,
        'trajectory': source,
        'effects_tested': list(settings.effects),
        'noise_floor_mm': 1e3 * settings.noise_floor_m,
    }
    rp = None
    if replan_trajectory and diag.effects_added:
        rp = replan(pattern_xy, diag, deployment, planner_settings, sim_settings, simulate, progress,
                    precompensation)
        unmodelled = [k for k in diag.fitted if k not in PLANNER_MODELS]
        report['replan'] = {'replanned': rp.replanned, 'original_predicted_e_mean_cm': rp.original_predicted_e_mean_cm,
                            'planner_L_gb_m': rp.planner_L_gb_m,
                            'planner_models': list(PLANNER_MODELS),
                            'not_in_the_planner': unmodelled,
                            'precompensation': rp.precompensation,
                            'robustness': rp.robustness}
        if rp.robustness is not None and not rp.robustness['robust']:
            w = rp.robustness['worst_e_mean_cm']
            worst = ('a simulation failed' if w is None else
                     f'up to {w:.3f} cm against {rp.original_predicted_e_mean_cm:.3f} cm for the original')
            report['warnings'].append(
                'the replanned trajectory, predicted better by the fitted rod, is not by rods beside it '
                f'({", ".join(sorted(diag.fitted))}, {ROBUSTNESS_NOTE}: {worst}): '
                'it sits near an instability, and the original trajectory is kept')
        elif not rp.replanned and simulate:
            report['warnings'].append('no replanned or pre-compensated trajectory is predicted by the fitted model to '
                                      'deploy better than the original one, which is kept')
        if unmodelled and not simulate:
            uses = 'only uses the fitted L_gb' if 'L_gb_m' in diag.fitted else 'is the original one'
            report['warnings'].append(f'the planner does not model {", ".join(unmodelled)}: they are pre-compensated '
                                      f'only with --simulate (the fitted simulator in the loop); the corrected '
                                      f'trajectory {uses}')
        if not rp.replanned:
            report['error_after'] = {'e_mean_cm': before['e_mean_cm'], 'sigma_cm': before['sigma_cm'],
                                     'coverage': before['coverage'],
                                     'source': 'unchanged: the original trajectory is kept',
                                     'fitted_model_e_mean_cm': rp.predicted_e_mean_cm}
        elif rp.predicted_xy is not None:
            after = eq17_error(pattern_xy, rp.predicted_xy, directed=True)
            report['error_after'] = {'e_mean_cm': after['e_mean_cm'], 'sigma_cm': after['sigma_cm'],
                                     'coverage': after['coverage'],
                                     'source': 'the corrected trajectory simulated with the fitted rod',
                                     'fitted_model_e_mean_cm_of_the_original': rp.original_predicted_e_mean_cm}
    else:
        report['error_after'] = {'e_mean_cm': before['e_mean_cm'], 'sigma_cm': before['sigma_cm'],
                                 'coverage': before['coverage'], 'source': 'unchanged: no effect added'}
        if replan_trajectory:
            report['warnings'].append('no effect added: nothing to replan (no corrected trajectory written)')
    report['simulations'] = diag.simulations + (rp.simulations if rp else 0)
    report['wall_time_s'] = time.perf_counter() - t0
    return report, diag, rp
