"""Feed-forward compensation of the drag of the laid rod at bends (issue #10; ``benchmarks/bend_drag_mechanism.py``).

The mechanism. At the optimal grasp (``optimal_grasp``) the suspended part pulls on the laid part at the touch-down
point with no force along the tangent, a lateral force F_y(kappa_bar) towards the inside of the bend and the
pattern's bending moment, and the table pushes there with a point force F_z(kappa_bar) (the lift-off boundary
layer). In units of k_b / L_gb^2 (= 2 w L_gb, w the rod's weight per length) both depend on kappa_bar alone
(ls_bar >= 5, any ks_bar: to 1 % at kappa_bar 4): F_y = 0.10, 0.22, 0.37, 0.57, 1.16, 2.01 and F_z = 0.75, 0.72,
0.67, 0.61, 0.49, 0.38 at |kappa_bar| = 0.25, 0.5, 0.75, 1, 1.5, 2 (F_y -> kappa_bar^2 / 2). The laid part carries
a lateral force at its end without friction only through its own curvature gradient (moment balance m' = -t x n:
the laid curve's d kappa_bar / d(s / L_gb) in the same units), so the touch-down point needs the friction

    D(s) = F_y(kappa_bar) + d kappa_bar / d(s / L_gb)        (released sign: > 0 pulls the laid rod to the right)

and holds it with at most mu F_z(kappa_bar). Entering a bend both terms add (the rate limit's ramp, 0.35 per L_gb,
is as large as F_y at |kappa_bar| 0.75); leaving it they cancel. Where |D| > mu F_z the laid rod behind the
touch-down point slides towards the inside of the bend: measured on rod #3's letter A at medium friction (DER),
the laid nodes moved 1.6-2.8 mm after touch-down exactly on the three stretches where the excess |D| - mu F_z is
positive (0.2-0.4), towards the inside every time, and < 0.6 mm elsewhere; the inward drag shortens the path
around the bend by about drag x turning angle, so the rest of the curve lags along it (5 mm on the letter A).

The compensation. ``drag_offsets``: the predicted drag at each node, ``DRAG_GAIN`` L_gb times the excess
(positive part), inwards; the planner is given a template, the pattern moved outwards by it (smoothed over
``DRAG_SMOOTHING_M``, ramped in from the free end over ``START_TAPER_M`` like ``refinement.py``), planned once more.
DRAG_GAIN is one number for every rod, pattern and friction: the least-squares slope of the measured drag on the
excess over the development runs (``benchmarks/bend_drag_mechanism.py``).
"""
from __future__ import annotations

import numpy as np

#: |kappa_bar| of the contact-force table (the grasp solver's range, ``PlannerSettings.max_abs_kappa_bar``)
CONTACT_KAPPA_BAR = np.arange(0.0, 4.001, 0.25)
#: F_y and F_z [k_b / L_gb^2] of the optimal grasp at the touch-down point (ls_bar 20, inextensible), per
#: CONTACT_KAPPA_BAR: ``contact_force_table()`` recomputes them (a test checks these against it)
CONTACT_FY = np.array([0.0, 0.1001, 0.2168, 0.3669, 0.5665, 0.8273, 1.1550, 1.5503, 2.0122, 2.5392, 3.1304,
                       3.7850, 4.5026, 5.2832, 6.1264, 7.0323, 8.0008])
CONTACT_FZ = np.array([0.7577, 0.7476, 0.7180, 0.6713, 0.6125, 0.5488, 0.4872, 0.4320, 0.3848, 0.3452, 0.3122,
                       0.2846, 0.2612, 0.2413, 0.2242, 0.2093, 0.1963])
#: predicted drag per unit of friction excess [L_gb] (least-squares slope on the development runs)
DRAG_GAIN = 0.30
#: Gaussian smoothing (sigma) of the predicted drag along the arc length [m]
DRAG_SMOOTHING_M = 0.01
#: the template offset ramps up from 0 at the free end over this arc length [m] (as refinement.py's)
START_TAPER_M = 0.03


def contact_force_table(kappa_bar=CONTACT_KAPPA_BAR, ls_bar=20.0):
    """(F_y, F_z) [k_b / L_gb^2] of the optimal grasp at the touch-down point per |kappa_bar| (the numeric solver,
    curvature continuation; seconds)."""
    from .optimal_grasp import optimal_grasp
    fy, fz, g = [], [], None
    for kb in np.asarray(kappa_bar, float):
        g = optimal_grasp(ls_bar, float(kb), np.inf, guess=g, check_stability=False)
        fy.append(float(g.clamp_force[1]))
        fz.append(float(g.clamp_force[2]))
    return np.array(fy), np.array(fz)


def friction_demand(s_bar, kappa_bar):
    """D (released sign, [k_b / L_gb^2]) per node: F_y(kappa_bar) + d kappa_bar / d s_bar, and F_z(|kappa_bar|)."""
    s_bar = np.asarray(s_bar, float)
    kappa_bar = np.asarray(kappa_bar, float)
    a = np.abs(kappa_bar)
    if np.any(a > CONTACT_KAPPA_BAR[-1] + 1e-9):
        raise ValueError(f'|kappa_bar| up to {a.max():.3g} is beyond the contact-force table '
                         f'({CONTACT_KAPPA_BAR[-1]:g})')
    fy = np.sign(kappa_bar) * np.interp(a, CONTACT_KAPPA_BAR, CONTACT_FY)
    fz = np.interp(a, CONTACT_KAPPA_BAR, CONTACT_FZ)
    return fy + np.gradient(kappa_bar, s_bar), fz


def friction_excess(s_bar, kappa_bar, friction):
    """(signed excess [k_b / L_gb^2]: sign(D) max(|D| - mu F_z, 0) per node, D per node)."""
    if not (np.isfinite(friction) and friction > 0):
        raise ValueError(f'friction must be positive, got {friction}')
    D, fz = friction_demand(s_bar, kappa_bar)
    return np.sign(D) * np.maximum(np.abs(D) - friction * fz, 0.0), D


def drag_offsets(s, tangent, kappa_bar, lgb_m, friction, gain=DRAG_GAIN, smoothing_m=DRAG_SMOOTHING_M,
                 start_taper_m=START_TAPER_M, start_m=0.0):
    """(m, 2) [m] template offsets per node (arc length ``s`` [m], unit ``tangent``, the planned ``kappa_bar``,
    released sign): the predicted drag, ``gain`` L_gb times the friction excess, smoothed, pointing outwards of the
    bend (against the drag); zero where friction holds the touch-down point and up to ``start_m`` (the planner: the
    length its friction-limited start replaced), ramped in over ``start_taper_m`` after it."""
    from scipy.ndimage import gaussian_filter1d
    s = np.asarray(s, float)
    excess, _ = friction_excess(s / lgb_m, kappa_bar, friction)
    drag = gain * lgb_m * excess
    if smoothing_m > 0 and len(s) > 1:
        drag = gaussian_filter1d(drag, smoothing_m / (s[1] - s[0]), mode='nearest')
    if start_taper_m > 0:
        u = np.clip((s - start_m) / start_taper_m, 0.0, 1.0)
        drag = drag * u * u * (3.0 - 2.0 * u)
    else:
        drag = np.where(s >= start_m, drag, 0.0)
    left = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    # D > 0 (released sign: a right turn) drags the laid rod to the right: the template moves left, and vice versa
    return drag[:, None] * left
