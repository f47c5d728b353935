"""Trajectory planning from a pattern (paper Alg. 4): the gripper poses that lay a rod along the pattern.

ProcessPattern: a smoothing spline through the pattern points (``smoothing_m``: the RMS distance the spline may keep
from them), resampled uniformly by arc length from its start to its end, the nodes at most ``step_m`` apart (the
largest spacing <= step_m that divides the spline's length, so that the last node is the pattern's end: with exactly
``step_m`` the last up to one step of every pattern was never planned nor laid); tangent T(s) and signed curvature
kappa(s) from the spline. For each node s (Alg. 4): q_C = P(s), x_hat = T(s), kappa_bar = kappa(s) L_gb,
ls_bar = (L - s) / L_gb (the rod not yet laid hangs between the connective node and the gripper), the grasp
(q_bar_M, R) = F(ls_bar, kappa_bar, ks_bar) from the network (``nn``), the numeric solver with curvature
continuation (``numeric``) or the paper's intuitive baseline (``intuitive``, Fig. 2a: the gripper straight above the
contact point at the height of the suspended length, moving along the tangent and down by the length laid, i.e. along
a 45-degree descent), then R_t = (x_hat, z_hat x x_hat, z_hat) and q_M = q_C + R_t q_bar_M L_gb.

The start (``start``): by default (``'achievable'``, ``achievable_start.py``) the pattern's start is replaced, before
the nodes are planned, by the closest curve whose curvature the table friction can hold near the moment-free end
(a start within that bound, e.g. a straight one, is left unchanged); ``'tangent'`` is Alg. 4 as written, every node
planned on the pattern itself. The intuitive baseline always uses the pattern as given. With ``looser_start`` (the
default, at table friction >= 0.5) a replaced start is planned once more counting on 1.5 times the bound, kept when
that brings the planned curve more than 0.5 mm nearer the pattern: where the bound keeps every curve centimetres
off (a loop drawn from its first point: the fresh rehearsal's digit 9 on rod #2, 1.9 cm for any curve within it)
the slip of a start asking 1.5 times the estimate costs less than the lost shape (our DER: 1.47 -> 0.88 cm;
``benchmarks/results/looser_start.md``).

The curvature asked of the grasp solver changes at most ``max_kappa_bar_rate`` per L_gb of pattern (by default
0.35 at table friction 0.5, scaled by sqrt(friction / 0.5); ``curvature_rate.py``): a faster change (a straight
stroke running into a tight curl) is spread over a ramp that keeps the pattern's turning; the contact points and
tangents stay the pattern's. Without it the optimal grasp,
which moves 5-6 L_gb per unit of kappa_bar at ls_bar 25, jumps by up to 17 cm between two 5 mm nodes, and the
sudden change of the bend's moment drags the laid rod (``benchmarks/grasp_jump.py``). The nodes are then planned on
one curve (``planned_curve='closest'``, the default): the curve nearest the pattern at equal arc length whose
curvature keeps the rate limit and the friction-limited start (``curvature_rate.closest_rate_limited_curve``), its
points, tangents and curvature agreeing, kept when it is nearer the pattern (mean distance over the nodes) than the
curve of the spread curvature (with ``free_start_point``, an option (off by default: CONTRACTS.md section 4 starts
every deployment with the free end at the pattern's first point), the
closest curve is fitted with its first point held at the pattern's and with it free, and the nearer of the two is
the candidate: near a free end friction holds only kappa_max(s) ~ s^2, so a start bent from its first point must
begin nearly straight, and a free end put down a few millimetres inside the bend lets that straight start straddle
the pattern instead of running outside it: letter C on rod #3, Eq. 17 of the planned curve 0.183 -> 0.114 cm,
deployed in our DER 0.375 -> 0.244 cm, ``benchmarks/start_floor.py``, ``benchmarks/results/start_point_comparison.md``);
otherwise (``'spread'``) the pattern's points and tangents with the spread curvature,
which rounds a corner wider than the pattern so that the later nodes lag along it (``asked_xy``: the curve the grasps
ask for, reported by ``rod-deploy plan``). With the default start, a
planned curve that table friction cannot hold - too tight a bend too close to the free end, where the laid part
is too short to resist its moment - is refused with the node named (``check_friction_holds``).

Drag compensation (``drag_compensation``, on by default; ``bend_drag.py``): where the planned curvature asks more
friction of the touch-down point than the table gives (the suspended part's lateral pull at a bend, plus the laid
curve's curvature gradient, against mu times the point reaction), the laid rod slides towards the inside of the bend
after touch-down, and what is laid after it is translated by that drag. The planner predicts the drag from the
planned curvature and plans once more, for the pattern moved against the translation from the free end on, the
friction-limited start included (``template``; the start is fitted again to it); ``pattern_as_given`` stays the
drawing.

The horizontal force at q_C (``shear``, issue #10): the laid rod at rest with the planned curvature needs none
along the tangent and the shear EI kappa' across it; the optimal grasp applies about EI kappa / (2.3 L_gb) across it
whatever kappa' is, and friction takes the difference. No grasp can match the shear: the hanging part turns
vertical and, twist free, carries no moment about the vertical whatever the gripper holds, so the moment about the
vertical through q_C balances as kappa EI = x_g F_y - y_g F_x (F the force on the laid rod in the local frame,
(x_g, y_g) the gripper's horizontal offset; ``benchmarks/shear_matched_grasp.py``). ``'least_force'`` (numeric
method) lets the force along the tangent go and takes the grasp of that family with the smallest horizontal force
(0.567 -> 0.419 EI / L_gb^2 at kappa_bar 1).

Sign of the curvature: kappa(s) > 0 turns left (towards z_hat x T, counter-clockwise seen from above); the grasp
solvers take the released code's kappa_bar = -kappa L_gb (positive turns right, see ``optimal_grasp``).

Gripper frame (CONTRACTS.md section 4): +z_gripper is the direction in which the rod leaves the gripper, i.e. minus
the rod's tangent at the gripper, R e_x; x_gripper = R e_z (the rod's material director d1 at the gripper, twist
free), y_gripper = z x x. A straight hanging rod for a pattern starting along -x has the quaternion (1, 0, 0, 0).
The trajectory starts at the hanging pose (free end on the table at the planned curve's first point - P(0), or with
``free_start_point`` up to about 1.5 cm from it where that brings a curved start nearer the pattern (letter C on rod
#3: 6.8 mm) - the rod straight up from it, the gripper
turned like the first grasp about the vertical), leads in along a straight line (orientation by slerp) to the first
grasp, then follows the pattern. Times: the gripper moves at ``speed_m_s`` and turns at most at
``max_angular_rate_rad_s``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.interpolate import splev, splprep
from scipy.spatial.transform import Rotation, Slerp

from .curvature_rate import default_max_rate, limit_curvature_rate
from .pattern_input import PatternError, check_pattern
from .rod_description import RodDescription

METHODS = ('nn', 'numeric', 'intuitive')
STARTS = ('tangent', 'achievable')
PLANNED_CURVES = ('closest', 'spread')
#: the horizontal force each node's grasp applies to the laid rod at q_C: 'moment_free' the paper's optimal grasp
#: (n0_x = 0, n0_y about -kappa_bar / 2.3 an output), 'least_force' the grasp of the moment-free family with n0_x
#: released whose horizontal force is smallest (numeric method only; issue #10, ``optimal_grasp.closest_shear_grasp``;
#: matching the laid curve's shear exactly is out of reach, benchmarks/shear_matched_grasp.py)
SHEARS = ('moment_free', 'least_force')
#: the table friction the 'achievable' start assumes when neither the settings nor the rod give one (medium)
DEFAULT_FRICTION = 0.5
#: the largest ``PlannerSettings.friction_share`` the start may count on (the bound is an estimate: the simulated rod
#: lays kappa_bar 0.48 at the letter C's start where c = 1 allows 0.39, benchmarks/results/free_end_laying.md)
MAX_FRICTION_SHARE = 2.0
#: the share the refusal (check_friction_holds) counts on at most, whatever the start's: a plan the rod cannot hold
#: drags the laid part by centimetres (HOLD_FACTOR is measured with it)
REFUSAL_FRICTION_SHARE = 1.0
#: ``PlannerSettings.looser_start``: the friction-limited start may count on LOOSER_START_FACTOR times the
#: friction_share (1.5: the refusal's own margin, HOLD_FACTOR) where that brings the planned curve nearer the
#: pattern by more than LOOSER_START_GAIN_M (mean distance over the nodes at equal arc length, Eq. 17's pairing).
#: Near a free end the bound's floor can be centimetres (a loop drawn from its first point: the digit 9 of the
#: fresh rehearsal, 1.9 cm for any curve within c = 1 on rod #2, 0.8 within the static bound c = 2), far more than
#: the slip of a start asking 1.5 times the estimate costs; where the looser start gains little (a straight or
#: gently bent start) the estimate stands (benchmarks/results/looser_start.md)
LOOSER_START_FACTOR = 1.5
LOOSER_START_GAIN_M = 0.0005
#: the looser start only at table friction >= LOOSER_START_MIN_FRICTION: HOLD_FACTOR was measured at friction 0.5-5;
#: at 0.2 the looser start laid rod #3's C, spiral and letter S worse (1.194 -> 1.270, 0.899 -> 0.911, 0.921 ->
#: 1.057 cm) and digit 2 and 6 better (benchmarks/results/looser_start_low.md)
LOOSER_START_MIN_FRICTION = 0.5
#: weight in the smoothing spline of the pattern points within END_ZONE_M of either end (the others: 1)
END_WEIGHT, END_ZONE_M = 30.0, 0.01
#: the gripper frame in the grasp solver's rotation R: columns (R e_z, R e_y, -R e_x)
GRIPPER_IN_GRASP_FRAME = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])


class PlanningError(ValueError):
    """A pattern or rod the planner cannot turn into a trajectory (never a partial trajectory)."""


@dataclass
class PlannerSettings:
    method: str = 'nn'
    step_m: float = 0.005                 # Alg. 4's step of deployment (largest node spacing along the pattern)
    smoothing_m: float = 0.0005           # RMS distance the smoothing spline may keep from the pattern points
    speed_m_s: float = 0.01               # gripper speed (quasi-static deployment)
    max_angular_rate_rad_s: float = 0.2   # gripper turning rate cap
    lead_in_poses: int = 20               # poses from the hanging pose to the first grasp
    min_ls_bar: float = 0.5               # the suspended part never shorter than this (the grasp data's range)
    max_abs_kappa_bar: float = 4.0        # the grasp data's range of curvature
    end_weight: float = END_WEIGHT        # spline weight of the points near the pattern's ends (process_pattern)
    start: str = 'achievable'             # 'achievable' (friction-limited, achievable_start.py) or 'tangent' (Alg. 4)
    friction: float | None = None         # table friction for the 'achievable' start; None: the rod's, else 0.5
    #: let the 'achievable' start count on LOOSER_START_FACTOR x friction_share where that brings the planned curve
    #: nearer the pattern by more than LOOSER_START_GAIN_M, at table friction >= LOOSER_START_MIN_FRICTION (the
    #: share used: ``PlannedTrajectory.friction_share``)
    looser_start: bool = True
    #: share c of the friction the 'achievable' start counts on (of the pure-moment capacity mu w s^2 / 4; c = 1
    #: plans exactly what c = 0.5 of the earlier, twice too large bound did: measured best, see achievable_start.py;
    #: up to MAX_FRICTION_SHARE, the bound being an estimate). The refusal (check_friction_holds) counts on
    #: min(c, 1) whatever c the start uses (REFUSAL_FRICTION_SHARE)
    friction_share: float = 1.0
    #: the largest |d kappa_bar / d(s / L_gb)| asked of the grasp solver (curvature_rate.py); None: the default for
    #: the table friction (0.35 at 0.5, scaled by sqrt(friction / 0.5)); inf: the pattern's own curvature (Alg. 4)
    max_kappa_bar_rate: float | None = None
    #: refuse a planned curve that table friction cannot hold (check_friction_holds, with the 'achievable' start);
    #: False plans it anyway (experiments: what such a pattern deploys to)
    check_friction: bool = True
    #: the curve the nodes are planned on: 'closest' (default) the curve closest to the pattern whose curvature
    #: respects the rate limit and the friction-limited start (``curvature_rate.closest_rate_limited_curve``; contact
    #: points, tangents and curvature of one curve); 'spread': the pattern's points and tangents with its curvature
    #: spread by the rate limit (``limit_curvature_rate``, the grasps asking a curvature the points do not have)
    planned_curve: str = 'closest'
    #: the closest planned curve's first point (where the free end is put down: the hanging pose is above it) may
    #: leave the pattern's first point: the curve is fitted with it held there and with it free
    #: (``closest_rate_limited_curve``), the nearer to the pattern kept; False (the default, CONTRACTS.md section 4:
    #: a deployment starts with the free end at the pattern's first point): held there
    free_start_point: bool = False
    #: plan for the pattern moved outwards of its bends by the drag that the friction excess at the touch-down point
    #: predicts (``bend_drag.py``); False: plan for the pattern itself
    drag_compensation: bool = True
    #: the horizontal force the grasps apply at q_C (``SHEARS``): 'moment_free' (the paper's optimal grasp) or
    #: 'least_force' (the smallest one a moment-free gripper can, a force along the tangent allowed; method 'numeric')
    shear: str = 'moment_free'

    def validate(self):
        if self.method not in METHODS:
            raise PlanningError(f'unknown method {self.method!r} (one of {", ".join(METHODS)})')
        if self.start not in STARTS:
            raise PlanningError(f'unknown start {self.start!r} (one of {", ".join(STARTS)})')
        if self.shear not in SHEARS:
            raise PlanningError(f'unknown shear {self.shear!r} (one of {", ".join(SHEARS)})')
        if self.shear != 'moment_free' and self.method != 'numeric':
            raise PlanningError(f"shear {self.shear!r} needs method 'numeric' (the network gives moment-free grasps only), "
                                f"got method {self.method!r}")
        if self.planned_curve not in PLANNED_CURVES:
            raise PlanningError(f'unknown planned_curve {self.planned_curve!r} (one of {", ".join(PLANNED_CURVES)})')
        if self.friction is not None and not (np.isfinite(self.friction) and self.friction > 0):
            raise PlanningError(f'friction must be positive, got {self.friction}')
        if not (np.isfinite(self.friction_share) and 0 < self.friction_share <= MAX_FRICTION_SHARE):
            raise PlanningError(f'friction_share must be in (0, {MAX_FRICTION_SHARE:g}], got {self.friction_share}')
        for name in ('step_m', 'speed_m_s', 'max_angular_rate_rad_s', 'min_ls_bar', 'max_abs_kappa_bar', 'end_weight'):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise PlanningError(f'{name} must be positive, got {v}')
        if self.max_kappa_bar_rate is not None and not (self.max_kappa_bar_rate > 0):     # inf: no limit
            raise PlanningError(f'max_kappa_bar_rate must be positive (inf: no limit), got {self.max_kappa_bar_rate}')
        if not (np.isfinite(self.smoothing_m) and self.smoothing_m >= 0):
            raise PlanningError(f'smoothing_m must be >= 0, got {self.smoothing_m}')


@dataclass
class ProcessedPattern:
    s: np.ndarray          # (m,) arc length [m]
    xy: np.ndarray         # (m, 2) points [m]
    tangent: np.ndarray    # (m, 2) unit tangents
    kappa: np.ndarray      # (m,) signed curvature [1/m], > 0 turning left
    #: the sharpest bend between the nodes too: (|turning angle| / arc length over one step [1/m], where (x, y) [m]);
    #: a bend shorter than a step (a cusp the spline rounds within a millimetre) can fall between two nodes
    peak_bend: tuple | None = None

    @property
    def length(self):
        return float(self.s[-1])


@dataclass
class PlannedTrajectory:
    t: np.ndarray                 # (n,) [s]
    position: np.ndarray          # (n, 3) held node of the rod, table frame [m]
    quaternion: np.ndarray        # (n, 4) gripper orientation, scalar-last
    pattern: ProcessedPattern     # the nodes of Alg. 4
    inputs: np.ndarray            # (m, 3) (ls_bar, ks_bar, kappa_bar) per node, released sign, kappa_bar rate-limited
    grasp_position: np.ndarray    # (m, 3) q_bar_M in the local frame [L_gb]
    grasp_rotvec: np.ndarray      # (m, 3)
    first_grasp_index: int        # row of the first pattern node (rows before it: hanging pose and lead-in)
    method: str
    timings_s: dict = field(default_factory=dict)
    #: the processed pattern before the friction-limited start replaced its beginning (``pattern`` when unchanged)
    pattern_as_given: ProcessedPattern | None = None
    #: the processed pattern with the friction-limited start only (``start_replacement``); ``pattern`` when the
    #: nodes are planned on it (planned_curve 'spread')
    start_pattern: ProcessedPattern | None = None
    #: (m, 2) [m] the curve the grasps ask the rod to lay: the planned curvature (rate-limited, ``inputs``) integrated
    #: from the free end at the planned curve's first point along its first tangent; None for the intuitive baseline
    #: (it asks no curvature: its grasp is the same whatever the pattern's)
    asked_xy: np.ndarray | None = None
    #: the processed template the nodes were planned for when drag compensation moved the pattern (``bend_drag.py``),
    #: else None
    template: ProcessedPattern | None = None
    #: the share of the friction the friction-limited start counted on (``PlannerSettings.friction_share``, or
    #: LOOSER_START_FACTOR times it with ``looser_start``); None without the 'achievable' start
    friction_share: float | None = None

    @property
    def rotation(self):
        return Rotation.from_quat(self.quaternion)

    @property
    def drawn_pattern(self) -> ProcessedPattern:
        """The processed pattern as drawn: ``pattern_as_given`` when set, else ``pattern``."""
        return self.pattern_as_given if self.pattern_as_given is not None else self.pattern

    def start_replacement(self, tol_m=1e-4):
        """(length [m] of the pattern's start that the friction-limited start replaces, the largest distance [m] from
        the pattern as drawn of the curve the grasps ask the rod to lay there (``asked_xy``, nearest point); (0, 0)
        when the pattern is planned as given. The distance is that of the planned curve, not of the start's first
        guess (``start_pattern``), which the closest planned curve and the looser start refit."""
        given = self.template if self.template is not None else self.pattern_as_given
        start = self.start_pattern if self.start_pattern is not None else self.pattern
        if given is None or given is start:
            return 0.0, 0.0
        k, length_m = _replaced_stretch(given, start, tol_m)
        if k == 0:
            return 0.0, 0.0
        curve = start.xy[:k] if self.asked_xy is None else self.asked_xy[self.pattern.s <= length_m + 1e-9]
        d = np.linalg.norm(curve[:, None, :] - self.drawn_pattern.xy[None, :, :], axis=2).min(axis=1)
        return length_m, float(d.max())

    def drag_offset_max(self):
        """The largest distance [m] of the drag compensation's template from the pattern as drawn (nearest point of
        the template's nodes); 0 when the pattern was planned as drawn."""
        if self.template is None:
            return 0.0
        t, g = self.template.xy, self.drawn_pattern.xy
        return float(np.max(np.min(np.linalg.norm(g[:, None, :] - t[None, :, :], axis=2), axis=1)))

    def asked_deviation(self):
        """(largest distance [m] of the curve the grasps ask for (``asked_xy``) from the pattern as drawn, at equal
        arc length (Eq. 17's pairing), the node where it is); (0, 0) for the intuitive baseline. It adds up what the
        planner changes on purpose: the friction-limited start and the curvature rate limit's spread bends."""
        if self.asked_xy is None:
            return 0.0, 0
        drawn = self.drawn_pattern
        asked = self.asked_xy
        if len(asked) != len(drawn.s):        # planned for a template (drag compensation): its own nodes
            asked = np.column_stack([np.interp(drawn.s, self.pattern.s, asked[:, k]) for k in range(2)])
        d = np.linalg.norm(asked - drawn.xy, axis=1)
        i = int(np.argmax(d))
        return float(d[i]), i


def _replaced_stretch(given: ProcessedPattern, start: ProcessedPattern, tol_m=1e-4):
    """(k, length [m]): the nodes of ``given`` from its first one up to the last that the friction-limited start
    ``start`` moved by more than ``tol_m``, and the arc length of ``given`` they span; (0, 0.0) when unchanged."""
    moved = np.flatnonzero(np.linalg.norm(start.xy - given.xy, axis=1) > tol_m)
    if moved.size == 0:
        return 0, 0.0
    k = int(moved[-1]) + 1
    return k, float(given.s[min(k, len(given.s) - 1)])


def process_pattern(points_xy, step_m=0.005, smoothing_m=0.0005, end_weight=END_WEIGHT) -> ProcessedPattern:
    """ProcessPattern of Alg. 4: smoothing spline, uniform arc-length resampling from end to end (nodes at most
    ``step_m`` apart), tangent, signed curvature.

    A smoothing spline is least constrained at its ends, where it spends its allowed distance from the points: with
    equal weights it leaves the published patterns' first point by 0.3-2 mm and turns their start by 0.4-5 degrees
    (a spurious end curvature), so the free end would not start at the pattern's first point and the laid shape would
    turn. The points within END_ZONE_M of each end (by chord length) weigh ``end_weight`` times the others: the
    spline starts within 0.2 mm of P(0) and within 1 degree of the points' own direction (2.4 on the spiral), the
    RMS distance to the points unchanged."""
    xy = check_pattern(points_xy)
    # parameterise by chord length so that the spline's parameter is close to arc length
    chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    k = 3 if len(xy) > 3 else 2
    w = np.where((chord <= END_ZONE_M) | (chord >= chord[-1] - END_ZONE_M), end_weight, 1.0)
    try:
        tck, _ = splprep([xy[:, 0], xy[:, 1]], u=chord / chord[-1], k=k, w=w, s=len(xy) * smoothing_m ** 2)
    except (ValueError, TypeError) as e:
        raise PatternError(f'the pattern cannot be fitted by a smoothing spline: {e}') from None
    u = np.linspace(0.0, 1.0, max(2000, 20 * len(xy)))
    dense = np.stack(splev(u, tck), axis=1)
    s_dense = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    length = s_dense[-1]
    if length < 2 * step_m:
        raise PatternError(f'the pattern is {length:.4g} m long, shorter than two steps of {step_m:g} m')
    n = int(np.ceil(length / step_m - 1e-9)) + 1         # the last node on the pattern's end
    s = np.linspace(0.0, length, n)
    uu = np.interp(s, s_dense, u)
    p = np.stack(splev(uu, tck), axis=1)
    d1 = np.stack(splev(uu, tck, der=1), axis=1)
    d2 = np.stack(splev(uu, tck, der=2), axis=1)
    speed = np.linalg.norm(d1, axis=1)
    if np.any(speed < 1e-12):
        i = int(np.argmin(speed))
        raise PatternError(f'the pattern has a cusp near ({p[i, 0]:.4g}, {p[i, 1]:.4g}) m (node {i}): it turns back '
                           f'on itself, which a rod cannot follow')
    tangent = d1 / speed[:, None]
    kappa = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / speed ** 3
    return ProcessedPattern(s=s, xy=p, tangent=tangent, kappa=kappa,
                            peak_bend=_peak_bend(dense, np.stack(splev(u, tck, der=1), axis=1), s_dense, step_m))


def _peak_bend(dense, d1, s_dense, window_m):
    """(largest |turning angle| / arc length over windows of ``window_m`` along the dense spline [1/m], its place)."""
    theta = np.unwrap(np.arctan2(d1[:, 1], d1[:, 0]))
    j = np.searchsorted(s_dense, s_dense + window_m)
    i = np.flatnonzero(j < len(s_dense))
    if i.size == 0:
        return None
    j = j[i]
    bend = np.abs(theta[j] - theta[i]) / (s_dense[j] - s_dense[i])
    k = int(np.argmax(bend))
    mid = int(np.argmax(np.abs(np.diff(theta[i[k]:j[k] + 1])))) + i[k]      # where the window turns most
    return float(bend[k]), dense[mid].copy()


def local_frames(tangent):
    """R_t = (x_hat, z_hat x x_hat, z_hat) per node, (m, 3, 3)."""
    m = len(tangent)
    R = np.zeros((m, 3, 3))
    R[:, 0, 0], R[:, 1, 0] = tangent[:, 0], tangent[:, 1]
    R[:, 0, 1], R[:, 1, 1] = -tangent[:, 1], tangent[:, 0]
    R[:, 2, 2] = 1.0
    return R


def node_inputs(pattern: ProcessedPattern, rod: RodDescription, settings: PlannerSettings) -> np.ndarray:
    """(ls_bar, ks_bar, kappa_bar) per node, with the checks that make a trajectory possible."""
    L, Lgb = rod.length_m, rod.gravito_bending_length_m
    ls_bar = (L - pattern.s) / Lgb
    short = np.flatnonzero(ls_bar < settings.min_ls_bar)
    if short.size:
        i = int(short[0])
        raise PlanningError(
            f'the pattern ({pattern.length:.3f} m) is longer than the rod allows: at node {i} '
            f'({pattern.xy[i, 0]:.4f}, {pattern.xy[i, 1]:.4f}) m only {L - pattern.s[i]:.4f} m of the {L:g} m rod '
            f'would remain suspended (at least {settings.min_ls_bar:g} L_gb = {settings.min_ls_bar * Lgb:.4f} m); '
            f'patterns up to {L - settings.min_ls_bar * Lgb:.3f} m fit this rod'
            + (' (a pattern file\'s values must be in metres)' if pattern.length > 20.0 else ''))
    kappa_bar = -pattern.kappa * Lgb                                   # the released sign
    sharp = np.flatnonzero(np.abs(kappa_bar) > settings.max_abs_kappa_bar)
    if sharp.size:
        i = int(sharp[0])
        raise PlanningError(
            f'the pattern bends too sharply for this rod at node {i} ({pattern.xy[i, 0]:.4f}, '
            f'{pattern.xy[i, 1]:.4f}) m: radius {1 / abs(pattern.kappa[i]):.4f} m, |kappa_bar| = '
            f'{abs(kappa_bar[i]):.3g} > {settings.max_abs_kappa_bar:g} (smallest radius the rod can follow: '
            f'{Lgb / settings.max_abs_kappa_bar:.4f} m); smooth the pattern (--smoothing) or use a stiffer rod')
    if pattern.peak_bend is not None and pattern.peak_bend[0] * Lgb > settings.max_abs_kappa_bar:
        bend, (x, y) = pattern.peak_bend
        raise PlanningError(
            f'the pattern bends too sharply for this rod at ({x:.4f}, {y:.4f}) m, between two nodes: it turns by '
            f'{np.degrees(bend * settings.step_m):.0f} degrees within {1000 * settings.step_m:g} mm (|kappa_bar| = '
            f'{bend * Lgb:.3g} > {settings.max_abs_kappa_bar:g}, a corner or cusp; smallest radius the rod can follow: '
            f'{Lgb / settings.max_abs_kappa_bar:.4f} m); round it off in the drawing or use a stiffer rod')
    return np.column_stack([ls_bar, np.full_like(ls_bar, rod.ks_bar), kappa_bar])


def check_friction_holds(pattern: ProcessedPattern, rod: RodDescription, friction, share):
    """PlanningError when table friction cannot hold the planned curve's curvature at some node (achievable_start.py's
    bound kappa_max(s), s from the free end, with its margin ``HOLD_FACTOR``): the bend's moment would turn the laid
    part and drag the free end, whatever the gripper does (the rehearsal's 10 cm hook with a 1.6 cm curl: e_mean
    9 cm, the free end dragged 7 cm). The curvature checked is the planned curve's own, before the rate limit
    spreads it: spread, the same bend still drags the free end (a 10 cm lead into a 1.7 cm curl: 10 cm)."""
    from .achievable_start import HOLD_FACTOR, HOLD_SLACK_KAPPA_BAR, friction_hold_violation
    Lgb = rod.gravito_bending_length_m
    i = friction_hold_violation(pattern.s, pattern.kappa * Lgb, Lgb, friction, share)
    if i is None:
        return
    kb = abs(float(pattern.kappa[i])) * Lgb
    need = Lgb * np.sqrt(8.0 * (kb - HOLD_SLACK_KAPPA_BAR) / (HOLD_FACTOR * share * friction))
    raise PlanningError(
        f'table friction {friction:g} cannot hold the pattern\'s bend at node {i} ({pattern.xy[i, 0]:.4f}, '
        f'{pattern.xy[i, 1]:.4f}) m, {pattern.s[i]:.3f} m from the free end: |kappa_bar| = {kb:.2f} (radius '
        f'{Lgb / kb:.3f} m) needs about {need:.2f} m of rod on the table before it, or the bend\'s moment turns the '
        f'laid part and drags the free end; start the pattern with a longer lead, draw the bend wider, or deploy '
        f'on a surface with more friction')


def grasps(inputs, method, progress=None, shear='moment_free'):
    """(position (m, 3) [L_gb], rotvec (m, 3)) for each node's inputs; ``shear`` (``SHEARS``): 'least_force' (method
    'numeric', ``PlannerSettings.validate`` checks it) the grasps with the least horizontal force at q_C
    (``optimal_grasp.least_force_sequence``)."""
    if method == 'nn':
        from .neural_controller import load_grasp_network
        return load_grasp_network().predict(inputs[:, 0], inputs[:, 1], inputs[:, 2])
    if method == 'numeric':
        from .optimal_grasp import grasp_sequence, least_force_sequence
        from .suspended_rod import BVPError
        try:
            seq = (least_force_sequence if shear == 'least_force' else grasp_sequence)(inputs, progress=progress)
        except (BVPError, RuntimeError, ValueError) as e:
            raise PlanningError(f'the numeric grasp solver failed along the pattern: {e}') from None
        return np.array([g.position for g in seq]), np.array([g.rotvec for g in seq])
    # intuitive (Fig. 2a): straight above the contact point at the height of the suspended length, rod vertical
    position = np.column_stack([np.zeros(len(inputs)), np.zeros(len(inputs)), inputs[:, 0]])
    rotvec = np.tile([0.0, -np.pi / 2, 0.0], (len(inputs), 1))
    return position, rotvec


def _planned_curve(given: ProcessedPattern, rod: RodDescription, settings: PlannerSettings, mu, drawn=None):
    """(the curve the nodes are planned on, its node inputs, the asked curve ``asked_xy``, the pattern with the
    friction-limited start only) for the processed pattern ``given`` and the table friction ``mu``; ``drawn``: the
    pattern as drawn when ``given`` is a template (drag compensation), checked first so that an error names a point
    of the drawing."""
    pattern = start_pattern = given
    if settings.start == 'achievable' and settings.method != 'intuitive':
        from .achievable_start import achievable_start
        # the pattern as drawn is checked first, so that an error names a point of it (the replaced start of a
        # pattern that bends too sharply strays far from it: 15 cm on a digit 3 with a cusp)
        node_inputs(given if drawn is None else drawn, rod, settings)
        pattern = achievable_start(pattern, rod.gravito_bending_length_m, mu, settings.friction_share,
                                   settings.max_abs_kappa_bar)
        start_pattern = pattern
    inputs = node_inputs(pattern, rod, settings)
    if settings.check_friction and settings.start == 'achievable' and settings.method != 'intuitive':
        check_friction_holds(pattern, rod, mu, min(settings.friction_share, REFUSAL_FRICTION_SHARE))
    if settings.method != 'intuitive':
        Lgb = rod.gravito_bending_length_m
        rate = settings.max_kappa_bar_rate if settings.max_kappa_bar_rate is not None else default_max_rate(mu)
        kappa_bar = limit_curvature_rate(inputs[:, 2], settings.step_m / Lgb, rate)
        from .achievable_start import friction_curvature_limit, integrate_curvature
        if settings.start == 'achievable':
            # a ramp may not bend the start more than friction holds there (where the planned curve does not)
            cap = np.maximum(np.abs(inputs[:, 2]),
                             friction_curvature_limit(pattern.s, Lgb, mu, settings.friction_share) * Lgb)
            kappa_bar = np.clip(kappa_bar, -cap, cap)

        def asked_curve(p, kb):     # the curve the grasps ask for: kappa_bar kb integrated from p's first node
            return integrate_curvature(p.s, np.arctan2(p.tangent[0, 1], p.tangent[0, 0]), -kb / Lgb, p.xy[0])[0]
        asked_xy = asked_curve(pattern, kappa_bar)
        if settings.planned_curve == 'closest' and np.isfinite(rate):
            from .curvature_rate import closest_rate_limited_curve
            cap = np.full(len(given.s), 0.9 * settings.max_abs_kappa_bar)
            if settings.start == 'achievable':
                cap = np.minimum(cap, friction_curvature_limit(given.s, Lgb, mu, settings.friction_share) * Lgb)
            theta0 = np.arctan2(pattern.tangent[0, 1], pattern.tangent[0, 0])

            def mean_distance(xy):
                return float(np.mean(np.linalg.norm(xy - given.xy, axis=1)))
            closest = closest_rate_limited_curve(given, -kappa_bar / Lgb, theta0, Lgb, rate, cap)
            if settings.free_start_point:
                # the same fit with the start point free; the fit is least squares, Eq. 17 the mean distance: the
                # freedom can lower the one and raise the other (the rehearsal's zig-zag: 2.29 -> 2.41 cm), so the
                # nearer of the two by mean distance is kept
                free = closest_rate_limited_curve(given, -kappa_bar / Lgb, theta0, Lgb, rate, cap,
                                                  free_start_point=True)
                if mean_distance(free.xy) < mean_distance(closest.xy):
                    closest = free
            # kept only when nearer the pattern (mean distance over the nodes at equal arc length, Eq. 17's e_mean)
            # than the curve of the spread curvature: the fit's limits and smoothing can leave it further (letter C
            # on rods #1-#2, our spiral: the friction-limited start held to kappa_max), and then it deployed worse
            if mean_distance(closest.xy) < mean_distance(asked_xy):
                pattern = closest
                inputs = node_inputs(pattern, rod, settings)
                kappa_bar = inputs[:, 2]
                asked_xy = asked_curve(pattern, kappa_bar)
        inputs[:, 2] = kappa_bar
    else:
        asked_xy = None
    return pattern, inputs, asked_xy, start_pattern


def _looser_start(given, rod, settings, mu, planned):
    """(settings, planned curve) with the friction-limited start counting on LOOSER_START_FACTOR times the share
    when that brings the curve the grasps ask for nearer the pattern (mean distance at equal arc length) by more than
    LOOSER_START_GAIN_M; else (settings, ``planned``) (``planned``: ``_planned_curve``'s answer at the settings'
    share). The refusal counts on min(c, REFUSAL_FRICTION_SHARE) either way."""
    share = min(LOOSER_START_FACTOR * settings.friction_share, MAX_FRICTION_SHARE)
    if share <= settings.friction_share:
        return settings, planned
    looser = replace(settings, friction_share=share)
    try:
        candidate = _planned_curve(given, rod, looser, mu)
    except PlanningError:
        return settings, planned

    def mean_distance(asked_xy):
        return float(np.mean(np.linalg.norm(asked_xy - given.xy, axis=1)))
    if mean_distance(candidate[2]) < mean_distance(planned[2]) - LOOSER_START_GAIN_M:
        return looser, candidate
    return settings, planned


def plan_trajectory(points_xy, rod: RodDescription, settings: PlannerSettings | None = None,
                    progress=None) -> PlannedTrajectory:
    """Alg. 4: gripper poses (table frame) that lay ``rod`` along the pattern ``points_xy`` [m]."""
    settings = settings or PlannerSettings()
    settings.validate()
    t0 = time.perf_counter()
    given = process_pattern(points_xy, settings.step_m, settings.smoothing_m, settings.end_weight)
    mu = settings.friction or rod.friction or DEFAULT_FRICTION
    pattern, inputs, asked_xy, start_pattern = _planned_curve(given, rod, settings, mu)
    if (settings.looser_start and start_pattern is not given and settings.method != 'intuitive'
            and mu >= LOOSER_START_MIN_FRICTION):
        settings, (pattern, inputs, asked_xy, start_pattern) = _looser_start(
            given, rod, settings, mu, (pattern, inputs, asked_xy, start_pattern))
    template = None
    if settings.drag_compensation and settings.method != 'intuitive':
        # bend_drag.py: plan once more for the pattern moved against the predicted drag's translation, from the
        # free end on (ramped in over START_TAPER_M): the drag within the friction-limited start translates the rest
        # too, and the start is fitted again to the moved template within the same friction bound
        from .bend_drag import drag_offsets
        kb = np.interp(given.s, pattern.s, inputs[:, 2])
        drag_offset = drag_offsets(given.s, given.tangent, kb, rod.gravito_bending_length_m, mu)
        if np.max(np.abs(drag_offset)) > 0:
            try:
                template = process_pattern(given.xy + drag_offset, settings.step_m, 0.0, settings.end_weight)
                pattern, inputs, asked_xy, start_pattern = _planned_curve(template, rod, settings, mu, drawn=given)
            except PlanningError:
                # the moved bend is one the planner refuses (e.g. too tight for the friction so near the free end,
                # where the drawn one passed): the pattern's own plan stands, reported with template None
                template = None
    t1 = time.perf_counter()
    qbar, rotvec = grasps(inputs, settings.method, progress, settings.shear)
    t2 = time.perf_counter()
    Lgb = rod.gravito_bending_length_m
    Rt = local_frames(pattern.tangent)
    # the connective node: the centreline of the rod lying on the table is at z = h (the grasp solver's floor)
    qc = np.column_stack([pattern.xy, np.full(len(pattern.xy), rod.radius_m)])
    position = qc + np.einsum('nij,nj->ni', Rt, qbar) * Lgb
    R_grip = Rt @ Rotation.from_rotvec(rotvec).as_matrix() @ GRIPPER_IN_GRASP_FRAME
    # the hanging pose: rod straight up from the planned curve's first point, gripper turned like the first grasp
    x0 = R_grip[0][:, 0].copy()
    x0[2] = 0.0
    if np.linalg.norm(x0) < 1e-6:
        x0 = np.array([-pattern.tangent[0, 0], -pattern.tangent[0, 1], 0.0])
    x0 /= np.linalg.norm(x0)
    z0 = np.array([0.0, 0.0, -1.0])
    hang_R = np.column_stack([x0, np.cross(z0, x0), z0])
    hang_p = np.array([pattern.xy[0, 0], pattern.xy[0, 1], rod.hanging_height_m])
    n_lead = max(int(settings.lead_in_poses), 1)
    lam = np.arange(n_lead) / n_lead
    lead_p = hang_p[None] + lam[:, None] * (position[0] - hang_p)[None]
    slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([hang_R, R_grip[0]])))
    lead_R = slerp(lam).as_matrix()
    all_p = np.vstack([lead_p, position])
    quat = Rotation.from_matrix(np.vstack([lead_R, R_grip])).as_quat()
    for i in range(1, len(quat)):                 # one hemisphere: no sign flips between neighbours
        if np.dot(quat[i], quat[i - 1]) < 0:
            quat[i] = -quat[i]
    t = trajectory_times(all_p, quat, settings.speed_m_s, settings.max_angular_rate_rad_s)
    return PlannedTrajectory(t=t, position=all_p, quaternion=quat, pattern=pattern, inputs=inputs,
                             grasp_position=qbar, grasp_rotvec=rotvec, first_grasp_index=n_lead,
                             method=settings.method, pattern_as_given=given, start_pattern=start_pattern,
                             asked_xy=asked_xy, template=template,
                             friction_share=(settings.friction_share if settings.start == 'achievable'
                                             and settings.method != 'intuitive' else None),
                             timings_s={'pattern': t1 - t0, 'grasps': t2 - t1, 'total': time.perf_counter() - t0})


def warm_up(rod: RodDescription, settings: PlannerSettings | None = None) -> float:
    """Load once what a process's first plan would (the network's weights, the compiled kernels from numba's cache,
    lazily imported modules: 0.4-0.6 s here, against tens of milliseconds for a plan) by planning a short bent
    stroke with the network and ``settings``' other choices; returns the seconds it took. ``rod-deploy plan`` reports it as
    ``startup_s``, apart from ``planning_time_s``; the planner node does it before it listens. Nothing is warmed for
    the intuitive baseline (it uses neither)."""
    settings = settings or PlannerSettings()
    if settings.method == 'intuitive':
        return 0.0
    t0 = time.perf_counter()
    lgb = rod.gravito_bending_length_m
    length = min(10.0 * lgb, 0.5 * rod.length_m)
    th = np.linspace(0.0, length / (4.0 * lgb), 40)                 # radius 4 L_gb: |kappa_bar| 0.25
    stroke = 4.0 * lgb * np.column_stack([np.sin(th), 1.0 - np.cos(th)])
    try:
        plan_trajectory(stroke, rod, replace(settings, method='nn', shear='moment_free'))
    except PlanningError:        # a stroke this rod cannot lay (a very short rod): the first plan loads them instead
        pass
    return time.perf_counter() - t0


def trajectory_times(position, quaternion, speed_m_s, max_angular_rate_rad_s, min_dt_s=1e-3):
    """Times of the poses: each segment at the gripper speed, slower where the turning rate would exceed its cap."""
    dp = np.linalg.norm(np.diff(position, axis=0), axis=1)
    dots = np.clip(np.abs(np.sum(quaternion[1:] * quaternion[:-1], axis=1)), 0.0, 1.0)
    dtheta = 2.0 * np.arccos(dots)
    dt = np.maximum(np.maximum(dp / speed_m_s, dtheta / max_angular_rate_rad_s), min_dt_s)
    return np.concatenate([[0.0], np.cumsum(dt)])
