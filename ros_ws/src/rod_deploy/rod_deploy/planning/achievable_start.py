"""The start of a pattern as the rod can hold it: friction-limited curvature near the free end.

A free end carries no moment. On the table, the laid part [0, s] (free end at s = 0) is held in its shape by the
table's friction alone. At the connective node q_C (arc length s) the suspended part acts on it with the pattern's
bending moment M = EI kappa(s) about the vertical and - the optimal grasp's gripper being moment-free and the force
along the tangent zero - a sideways force of only F = M / x_g, x_g the gripper's horizontal lead ahead of q_C (2.4-2.6
L_gb along the grasp data for ls_bar >= 4; the DER statics of ``benchmarks/deployment_decomposition.py --statics``
finds M / F = 2.4-2.5 L_gb). Friction on a straight laid stretch of weight w per length, turning rigidly about a
point y0 of it (y = x - s in [-s, 0]), gives at most F = mu w (-2 y0 - s) and M = mu w (s^2 / 2 - y0^2): with no net
force (y0 = -s / 2) a moment of mu w s^2 / 4, half the mu w s^2 / 2 of all of [0, s] slipping one way (which needs a
net sideways force mu w s that nothing supplies; the bound before this correction counted on it). With the
sideways force M / x_g the capacity is lower still, mu w C(s) with C(s) = x_g (2 sqrt(x_g^2 + x_g s + s^2 / 2) - 2 x_g
- s) (``friction_moment_capacity_m2``: 0.89 s^2 / 4 at s = 2 cm, 0.65 s^2 / 4 at 8 cm for rod #3). The planner uses the
pure-moment bound (the s^2 growth keeps it a statement about the start only; the sideways force's share is left to
c): with EI = 2 w L_gb^3 (the contract's L_gb) the rod can hold at most

    |kappa(s)| <= kappa_max(s) = c mu s^2 / (8 L_gb^3),    i.e.  |kappa_bar(s)| <= c mu (s / L_gb)^2 / 8,

(c the share of the friction the planner counts on, up to 2, the refusal below counting on min(c, 1);
``PlannerSettings.friction_share``, default 1: the same
plans as the earlier bound mu s^2 / (4 L_gb^3) with its share 0.5, the version measured best on the full
deployments; c = 0.5 of the corrected bound made the full letter C worse, 0.34 -> 0.67 cm: its start strays 18 mm
from the pattern, which costs more than the slip it avoids; the planner counts on 1.5 c where that brings the
planned curve more than 0.5 mm nearer the pattern, ``PlannerSettings.looser_start``), and a pattern's curvature kappa_bar needs a straight-ish start of about
2 sqrt(2) L_gb sqrt(|kappa_bar| / (c mu)) before the rod can follow it. A tangent start that asks for more is left by
the rod once the free end is released: the laid start turns about a point of it and the rest of the shape turns
with it (clamping the first 3 nodes of the rod on the pattern in the simulator removes that turn: letter C, first
0.25 m, start -21 -> -1.6 degrees, ``benchmarks/results/deployment_decomposition.md``).

``achievable_start`` replaces the start of the processed pattern by the curve closest to it (least squares on the
nodes, same arc length, the same first point: the free end stays at P(0)) whose curvature respects kappa_max: the
start heading and a curvature correction on the first ``S_c`` of the pattern (piecewise linear, zero at S_c) are the
unknowns, the rate of change of the planned curvature is penalised (``BEND_RATE_WEIGHT``: the grasp follows the
curvature, so an oscillating catch-up would swing the gripper); beyond S_c the planned curve's curvature is the
pattern's, so a correction that returns the curve onto the
pattern's position and heading at S_c leaves the rest exactly on it. This is the paper's "remainder" (Sec. 6.4.1,
a start whose curvature grows from zero) chosen to minimise the deviation from the pattern, without moving the free
end off the pattern's first point. Patterns that never ask for more than kappa_max are returned unchanged.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares



#: weight of the rate of change of the planned curvature, d kappa_bar / d(s / L_gb), against the distance from the
#: pattern (in L_gb): without it the least-squares start catches up with the pattern by a curvature that oscillates
#: (letter C: kappa_bar -0.77, +0.13, -0.60 within 3 cm), which swings the gripper by centimetres
BEND_RATE_WEIGHT = 0.3


def friction_moment_capacity_m2(s_m, lever_m):
    """C(s) [m^2]: the largest moment about the vertical friction gives a rigid straight laid stretch [0, s], per
    mu w, when the load at its end is a moment M with a sideways force M / lever (see the module docstring)."""
    s = np.asarray(s_m, float)
    x = float(lever_m)
    return x * (2.0 * np.sqrt(x * x + x * s + 0.5 * s * s) - 2.0 * x - s)


def friction_curvature_limit(s_m, gravito_bending_length_m, friction, share=1.0):
    """kappa_max(s) [1/m]: the largest curvature friction can hold at arc length s from a free end, c mu s^2 /
    (8 L_gb^3) (the pure-moment capacity mu w s^2 / 4 over EI = 2 w L_gb^3)."""
    return share * friction * np.asarray(s_m, float) ** 2 / (8.0 * gravito_bending_length_m ** 3)


def start_length_needed_m(kappa_bar, gravito_bending_length_m, friction, share=1.0):
    """Arc length from the free end after which |kappa_bar| can be held: 2 sqrt(2) L_gb sqrt(|kappa_bar| / (c mu))."""
    return 2.0 * np.sqrt(2.0) * gravito_bending_length_m * np.sqrt(np.abs(kappa_bar) / (share * friction))


#: the planner refuses a planned curve asking more than HOLD_FACTOR times kappa_max(s) (plus HOLD_SLACK_KAPPA_BAR)
#: anywhere: the bound is an estimate (a rigid straight stretch); measured in benchmarks/grasp_jump.py on a straight
#: lead followed by a curl of kappa_bar 2 and on the rehearsal's hook at friction 0.5-5: deployments that asked up to
#: 1.1 times the bound laid the curl (e_mean 0.37 cm), those asking 1.6 times or more dragged the laid part (3.4-9 cm)
HOLD_FACTOR = 1.5
#: excess curvature [kappa_bar] tolerated: the fitted start may exceed the bound at its first centimetres (by 0.07
#: over HOLD_FACTOR kappa_max on an S-curve starting on a 17 cm radius, by 0.1 over kappa_max on a cursive e);
#: the check is for bends far beyond it (the hook: 1.6 over HOLD_FACTOR kappa_max)
HOLD_SLACK_KAPPA_BAR = 0.25


def friction_hold_violation(s_m, kappa_bar, gravito_bending_length_m, friction, share=1.0):
    """Index of the node whose planned |kappa_bar| friction can least hold - more than HOLD_FACTOR kappa_max(s)
    L_gb + HOLD_SLACK_KAPPA_BAR - or None when friction holds the whole planned curve."""
    kmax = friction_curvature_limit(s_m, gravito_bending_length_m, friction, share) * gravito_bending_length_m
    over = np.abs(np.asarray(kappa_bar, float)) - HOLD_SLACK_KAPPA_BAR - HOLD_FACTOR * kmax
    i = int(np.argmax(over))
    return i if over[i] > 0 else None


def _cumtrapz(f, ds):
    """Cumulative trapezoids of f (m, ...) on steps ds (m - 1,), starting at 0."""
    inc = 0.5 * (f[1:] + f[:-1]) * ds.reshape((-1,) + (1,) * (f.ndim - 1))
    return np.concatenate([np.zeros((1,) + f.shape[1:]), np.cumsum(inc, axis=0)])


def integrate_curvature(s, theta0, kappa, origin):
    """Curve with heading theta0 + int kappa from ``origin`` (trapezoids): (xy (m, 2), heading (m,))."""
    ds = np.diff(s)
    theta = theta0 + np.concatenate([[0.0], np.cumsum(0.5 * (kappa[1:] + kappa[:-1]) * ds)])
    c, si = np.cos(theta), np.sin(theta)
    x = origin[0] + np.concatenate([[0.0], np.cumsum(0.5 * (c[1:] + c[:-1]) * ds)])
    y = origin[1] + np.concatenate([[0.0], np.cumsum(0.5 * (si[1:] + si[:-1]) * ds)])
    return np.column_stack([x, y]), theta


def achievable_start(pattern, gravito_bending_length_m: float, friction: float, share=1.0,
                     max_abs_kappa_bar=4.0, knots=10) -> ProcessedPattern:
    """The pattern with its start replaced by the closest curve the rod can hold (see the module docstring)."""
    s, Lgb = pattern.s, gravito_bending_length_m
    kappa_max = friction_curvature_limit(s, Lgb, friction, share)
    over = np.flatnonzero(np.abs(pattern.kappa) > kappa_max)
    if over.size == 0:
        return pattern
    # the corrected stretch: three times the last point asking too much, at least 3 cm, at most half the pattern
    s_c = float(np.clip(3.0 * s[over[-1]], 0.03, 0.5 * pattern.length))
    n_c = int(np.searchsorted(s, s_c))
    s_knots = np.linspace(0.0, s[n_c], knots + 1)          # the last knot (S_c) carries no correction
    hat = np.clip(1.0 - np.abs(s[:, None] - s_knots[None, :-1]) / (s_knots[1] - s_knots[0]), 0.0, None)
    hat[n_c + 1:] = 0.0
    theta_p = np.arctan2(pattern.tangent[0, 1], pattern.tangent[0, 0])
    theta_c = np.arctan2(pattern.tangent[n_c, 1], pattern.tangent[n_c, 0])
    kappa_cap = np.minimum(kappa_max, 0.9 * max_abs_kappa_bar / Lgb)[:n_c + 1]
    sc, kappa_p, hat = s[:n_c + 1], pattern.kappa[:n_c + 1], hat[:n_c + 1]
    w_pen = 10.0 * np.sqrt(n_c + 1)      # constraint violations weigh like 10 x the whole fit, the junction 100 x
    w_smooth = 1e-2
    w_bend_rate = BEND_RATE_WEIGHT                # the planned curvature changes smoothly (the grasp follows it)

    def curve(x):
        kappa = kappa_p + hat @ x[1:] / Lgb
        xy, theta = integrate_curvature(sc, theta_p + x[0], kappa, pattern.xy[0])
        return kappa, xy, theta

    ds = np.diff(sc)
    # d theta / d x: the start heading, and each knot's correction integrated (the curve is linear in theta)
    dtheta = np.column_stack([np.ones(n_c + 1), _cumtrapz(hat, ds) / Lgb])
    smooth = w_smooth * np.diff(np.eye(knots), axis=0)

    def residuals(x):
        kappa, xy, theta = curve(x)
        fit = (xy - pattern.xy[:n_c + 1]).ravel() / Lgb
        junction = np.concatenate([(xy[-1] - pattern.xy[n_c]) / Lgb, [np.angle(np.exp(1j * (theta[-1] - theta_c)))]])
        excess = np.maximum(np.abs(kappa) - kappa_cap, 0.0) * Lgb
        rate = w_bend_rate * np.diff(kappa) / ds * Lgb ** 2
        return np.concatenate([fit, 10 * w_pen * junction, w_pen * excess, smooth @ x[1:], rate])

    def jacobian(x):
        kappa, _, theta = curve(x)
        dx = _cumtrapz(-np.sin(theta)[:, None] * dtheta, ds) / Lgb
        dy = _cumtrapz(np.cos(theta)[:, None] * dtheta, ds) / Lgb
        fit = np.stack([dx, dy], axis=1).reshape(2 * (n_c + 1), -1)
        junction = np.vstack([dx[-1], dy[-1], dtheta[-1]])
        active = (np.abs(kappa) > kappa_cap) * np.sign(kappa)
        excess = np.column_stack([np.zeros(n_c + 1), active[:, None] * hat])
        rate = w_bend_rate * np.column_stack([np.zeros(n_c), np.diff(hat, axis=0) / ds[:, None] * Lgb])
        return np.vstack([fit, 10 * w_pen * junction, w_pen * excess,
                          np.column_stack([np.zeros(knots - 1), smooth]), rate])

    # start from the clipped curvature (what the rod would lay), heading unchanged
    x0 = np.zeros(knots + 1)
    x0[1:] = np.linalg.lstsq(hat, (np.clip(kappa_p, -kappa_cap, kappa_cap) - kappa_p) * Lgb, rcond=None)[0]
    sol = least_squares(residuals, x0, jac=jacobian, method='trf', ftol=1e-6, xtol=1e-6, gtol=1e-8, max_nfev=100)
    kappa, xy, theta = curve(sol.x)
    from .trajectory import ProcessedPattern
    tangent = np.column_stack([np.cos(theta), np.sin(theta)])
    return ProcessedPattern(s=s.copy(), xy=np.vstack([xy, pattern.xy[n_c + 1:]]),
                            tangent=np.vstack([tangent, pattern.tangent[n_c + 1:]]),
                            kappa=np.concatenate([kappa, pattern.kappa[n_c + 1:]]))
