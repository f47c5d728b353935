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

What the local drag misses (``benchmarks/drag_residual.py``, ``drag_residual.md``): the templates the refinement
in the loop (``refinement.py``) converges to differ from the local drag's (the pattern moved outwards by DRAG_GAIN
L_gb times the excess where the excess is) after the bends, not at them. After the first bend of rod #3's letter C
the default deployment is off by -3 mm, then +3 mm along a wide arc where friction holds everything, the sign
changing as a translation's normal component does, with the rest of the curve about 3.5 mm behind along it; on the
letter A the same after each bend. The rod dragged inwards at a bend is laid on from where it was dragged to: what
follows is translated by the drag, and that translation fades only over decimetres (as the gripper, placed on
the pattern, pulls the touch-down point back).

The compensation. ``drag_terms`` has two terms per unit gain: ``drag``, L_gb times the excess where it is
(smoothed over ``DRAG_SMOOTHING_M``; the one-constant model of the seventh round, DRAG_GAIN the least-squares slope
of the measured drag on the excess, ``bend_drag_mechanism.py``), and ``shift``, against the translation: the excess
integrated along the inward normal, Lambda(s) = int excess(s') n_in(s') exp(-(s - s') / DRAG_SHIFT_M) ds', the
template moved by -Lambda along its normal. ``drag_offsets`` adds them with ``DRAG_GAINS`` (drag 0, shift 0.43: the
least-squares fit of the shift term to 6 refined templates of the eleventh round's planner, rods #2-#3 at friction
0.5, offsets from the free end on, ``drag_model_fit.py``, ``drag_model_fit_r12.md``; the eleventh round's 0.40 at a
leak of 0.2 m was fitted beyond the friction-limited start only; in a sweep at shift gain 0.42, rod #3's letter A
laid 0.393 cm with the drag term at 0.30 as well, 0.210 with the shift term alone, against 0.242 with the drag term
alone: ``drag_terms_sweep_rods23_mu0.5.md``). The translation hardly fades (``DRAG_SHIFT_M`` 1 m; the fit is flat
from 0.6 m on): once friction holds the laid rod where it was dragged, nothing pulls it back.

Within the friction-limited start too (the twelfth round, ``drag_residual_r12_*.md``): the refined templates of the
letters C and G move 3-5 mm outwards within the start's first 12 cm, where the default deployments lie 4-6 mm
inwards, and the other way after it; the start's curvature ramp asks more of the touch-down point than friction
holds there as well. The planner is given the pattern moved by the offsets from the free end on (ramped in over
``START_TAPER_M``, like ``refinement.py``; the free end stays at the pattern's first point) and plans once more,
the friction-limited start fitted again to the moved template within the same bound.
One set of constants for every rod, pattern and friction (fitted at friction 0.5 only). At friction 0.2 the refined
templates (rod #3's letters A, C, digit 2) fit the shift gain 0.36 at the eleventh round's leak, against 0.40 at
0.5 (``drag_residual_low.md``, ``drag_model_fit_low.md``): the needed correction scales with the friction excess,
which carries mu, so the gains do not depend on friction. A gate that applied the offsets within the start only
below friction 0.5 (h-low12, ``low_friction_drag_summary.md``: rod #3's paper 7 at 0.2 0.509 -> 0.418 cm) was
superseded by the offsets from the free end at every friction (0.509 -> 0.371, ``deployment_table_r12_rod3_low.md``).
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
#: gains of the two terms (drag, shift) of ``drag_terms``: the shift term alone, its gain the least-squares fit to
#: the refined templates of 6 development cases of the eleventh round's planner, offsets from the free end on
#: (``benchmarks/drag_model_fit.py``, its default; leak DRAG_SHIFT_M; ``drag_model_fit_r12.md``); the drag term
#: added to it laid worse in our DER (``benchmarks/results/drag_terms_sweep_rods23_mu0.5.md``)
DRAG_GAINS = (0.0, 0.43)
#: leak length of the shift term's translation [m] (inf: it persists): the fit's leave-one-out RMS is flat from 0.6
#: m on (0.2 m, the eleventh round's, fitted before the offsets reached into the start: 1.93 against 1.72 mm)
DRAG_SHIFT_M = 1.0
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


def drag_terms(s, tangent, kappa_bar, lgb_m, friction, shift_m=np.inf, smoothing_m=DRAG_SMOOTHING_M,
               start_taper_m=START_TAPER_M, start_m=0.0):
    """The compensation's two terms per unit gain, each (m, 2) [m] template offsets per node (arc length ``s`` [m],
    unit ``tangent``, the planned ``kappa_bar``, released sign), zero up to ``start_m`` and ramped in over
    ``start_taper_m`` after it:

    drag: L_gb times the friction excess, smoothed over ``smoothing_m``, outwards of the bend;
    shift: against the translation of the rest of the curve by the drag: the laid rod dragged inwards at a bend
    is laid on from where it was dragged to, so what follows is translated by the drag (measured: rod #3's letter C
    after its start, 3.5 mm inwards of its first bend, normal deviation changing sign along the arc as a translation
    does), Lambda(s) = int_0^s excess(s') (inwards unit vector at s') ds' per unit gain, leaking over
    ``shift_m``; the template moved by -Lambda, along its normal (the tangential part only reparametrises).
    The excess counts everywhere (the drag within the start is real); only the offsets are zero in it."""
    from scipy.ndimage import gaussian_filter1d
    s = np.asarray(s, float)
    tangent = np.asarray(tangent, float)
    kappa_bar = np.asarray(kappa_bar, float)
    if not shift_m > 0:
        raise ValueError(f'the shift leak length must be positive (inf: none), got {shift_m}')
    excess, _ = friction_excess(s / lgb_m, kappa_bar, friction)
    if start_taper_m > 0:
        u = np.clip((s - start_m) / start_taper_m, 0.0, 1.0)
        ramp = u * u * (3.0 - 2.0 * u)
    else:
        ramp = (s >= start_m).astype(float)
    ds = np.diff(s, prepend=s[0])
    drag = lgb_m * excess
    if smoothing_m > 0 and len(s) > 1:
        drag = gaussian_filter1d(drag, smoothing_m / (s[1] - s[0]), mode='nearest')
    left = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    inward = -excess[:, None] * left                        # excess > 0 drags to the right (-left)
    translation = np.zeros_like(inward)
    acc = np.zeros(2)
    for i in range(len(s)):
        acc = acc * np.exp(-ds[i] / shift_m) + inward[i] * ds[i]
        translation[i] = acc
    shift = -np.sum(translation * left, axis=1)
    # D > 0 (released sign: a right turn) drags the laid rod to the right: the template moves left, and vice versa
    return tuple((v * ramp)[:, None] * left for v in (drag, shift))


def drag_offsets(s, tangent, kappa_bar, lgb_m, friction, gains=None, shift_m=None,
                 smoothing_m=DRAG_SMOOTHING_M, start_taper_m=START_TAPER_M, start_m=0.0):
    """(m, 2) [m] template offsets per node (arc length ``s`` [m], unit ``tangent``, the planned ``kappa_bar``,
    released sign): the sum of :func:`drag_terms` times ``gains`` (drag, shift; default ``DRAG_GAINS``);
    zero where friction holds the touch-down point and up to ``start_m`` (the planner: 0, from the free end on;
    ``benchmarks/drag_model_fit.py --beyond-start``: the length the friction-limited start replaced), ramped in over
    ``start_taper_m`` after it."""
    gains = DRAG_GAINS if gains is None else gains
    if len(gains) != 2 or not all(np.isfinite(g) for g in gains):
        raise ValueError(f'two finite gains (drag, shift) expected, got {gains!r}')
    terms = drag_terms(s, tangent, kappa_bar, lgb_m, friction, DRAG_SHIFT_M if shift_m is None else shift_m,
                       smoothing_m, start_taper_m, start_m)
    return sum(g * t for g, t in zip(gains, terms))
