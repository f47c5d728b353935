"""The drag at bends: the contact-force table, the friction demand and excess, the planner's compensation."""
import numpy as np
import pytest

from rod_deploy.planning.bend_drag import (CONTACT_FY, CONTACT_FZ, CONTACT_KAPPA_BAR, DRAG_GAIN, DRAG_GAINS,
                                           DRAG_SHIFT_M, contact_force_table, drag_offsets, drag_terms,
                                           friction_demand, friction_excess)
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

ROD3 = {'length': 0.89, 'radius': 0.002, 'L_gb': 0.034}


def test_stored_contact_forces_are_the_grasp_solvers():
    k = CONTACT_KAPPA_BAR[[0, 2, 4, 8]]                      # 0, 0.5, 1, 2
    fy, fz = contact_force_table(k)
    np.testing.assert_allclose(fy, CONTACT_FY[[0, 2, 4, 8]], atol=2e-4)
    np.testing.assert_allclose(fz, CONTACT_FZ[[0, 2, 4, 8]], atol=2e-4)
    # the lateral pull grows like kappa_bar^2 / 2 and the point reaction falls: the touch-down point holds less
    assert CONTACT_FY[-1] == pytest.approx(CONTACT_KAPPA_BAR[-1] ** 2 / 2, rel=0.01)
    assert np.all(np.diff(CONTACT_FY) > 0) and np.all(np.diff(CONTACT_FZ) < 0)


def test_demand_on_an_arc_is_the_lateral_pull_and_a_ramp_adds_or_cancels():
    s = np.linspace(0.0, 3.0, 31)
    D, fz = friction_demand(s, np.full_like(s, 1.0))          # an arc turning right at kappa_bar 1
    np.testing.assert_allclose(D, 0.5665, atol=1e-3)
    np.testing.assert_allclose(fz, 0.6125, atol=1e-3)
    D_left, _ = friction_demand(s, np.full_like(s, -1.0))     # mirrored: pulled the other way
    np.testing.assert_allclose(D_left, -D)
    D_in, _ = friction_demand(s, 0.5 + 0.2 * s)               # entering a bend: the ramp adds 0.2
    D_out, _ = friction_demand(s, 1.1 - 0.2 * s)              # leaving it: the ramp takes 0.2 off
    i = 15                                                    # kappa_bar 0.8 on both
    assert D_in[i] - D_out[i] == pytest.approx(0.4, abs=1e-6)


def test_excess_only_where_friction_cannot_hold():
    s = np.linspace(0.0, 3.0, 31)
    e, _ = friction_excess(s, np.full_like(s, 1.0), 0.5)
    np.testing.assert_allclose(e, 0.5665 - 0.5 * 0.6125, atol=1e-3)
    e, _ = friction_excess(s, np.full_like(s, 1.0), 1.0)      # high friction holds kappa_bar 1
    assert np.all(e == 0.0)
    e, _ = friction_excess(s, np.zeros_like(s), 0.2)          # a straight line never drags
    assert np.all(e == 0.0)
    with pytest.raises(ValueError, match='friction'):
        friction_excess(s, np.zeros_like(s), 0.0)
    with pytest.raises(ValueError, match='beyond the contact-force table'):
        friction_demand(s, np.full_like(s, 4.5))


@pytest.mark.parametrize('turn', [1.0, -1.0])
def test_offsets_point_out_of_the_bend(turn):
    lgb = 0.034
    s = np.linspace(0.0, 0.3, 61)
    kb = turn * np.clip((s - 0.1) / 0.05, 0.0, 1.0)           # straight, then a ramp into kappa_bar +-1
    tangent = np.tile([1.0, 0.0], (len(s), 1))                # the offsets' sign only needs the local frame
    for gains in (DRAG_GAINS, (DRAG_GAIN, 0.0)):
        off = drag_offsets(s, tangent, kb, lgb, 0.5, gains=gains)
        assert np.all(off[:, 0] == 0.0)
        assert np.all(np.abs(off[s < 0.03, 1]) < 1e-4)        # tapered in from the free end
        # right turn (kappa_bar > 0, released sign): the laid rod is dragged right, the template moves left (+y)
        assert np.sign(off[-1, 1]) == turn
    # the drag term: DRAG_GAIN L_gb x the excess on the arc
    assert abs(off[-1, 1]) == pytest.approx(DRAG_GAIN * lgb * (0.5665 - 0.5 * 0.6125), rel=0.02)
    # the shift term (the default): the excess integrated along the straight frame, leaking over DRAG_SHIFT_M
    excess, _ = friction_excess(s / lgb, kb, 0.5)
    w = np.exp(-(s[-1] - s) / DRAG_SHIFT_M) * np.diff(s, prepend=0.0)
    assert drag_offsets(s, tangent, kb, lgb, 0.5)[-1, 1] == pytest.approx(DRAG_GAINS[1] * np.sum(excess * w),
                                                                          rel=1e-9)


def _arc_pattern(radius, lead=0.15, turn=np.pi):
    a = np.linspace(0.0, turn, 200)[1:]
    line = np.column_stack([np.linspace(0.0, lead, 100), np.zeros(100)])
    arc = np.column_stack([lead + radius * np.sin(a), -radius + radius * np.cos(a)])     # turning right
    return np.vstack([line, arc])


def test_planner_moves_a_tight_bend_outwards_and_leaves_a_held_one_alone():
    rod = rod_description_from_dict(ROD3)
    P = _arc_pattern(0.034)                                   # |kappa_bar| 1 after a 15 cm lead
    plain = plan_trajectory(P, rod, PlannerSettings(friction=0.5, drag_compensation=False))
    comp = plan_trajectory(P, rod, PlannerSettings(friction=0.5))
    assert plain.template is None and comp.template is not None
    g = comp.drawn_pattern
    d = np.array([np.min(np.linalg.norm(comp.template.xy - p, axis=1)) for p in g.xy])
    assert d[g.s < 0.02].max() < 2e-4                         # the start stays on the pattern
    assert 0.002 < d.max() < 0.010                            # the bend moved by about the predicted translation
    assert comp.drag_offset_max() == pytest.approx(d.max()) and plain.drag_offset_max() == 0.0
    centre = np.array([0.15, -0.034])                          # outwards: further from the arc's centre
    k = int(np.argmax(d))
    j = int(np.argmin(np.linalg.norm(comp.template.xy - g.xy[k], axis=1)))
    assert np.linalg.norm(comp.template.xy[j] - centre) > np.linalg.norm(g.xy[k] - centre)
    n = min(len(comp.position), len(plain.position))        # the template is longer: a node or more
    assert np.abs(comp.position[:n] - plain.position[:n]).max() > 1e-3
    dev, _ = comp.asked_deviation()                           # reported against the pattern as drawn
    assert 0 < dev < 0.02
    # high friction holds a bend of kappa_bar 0.5 and its ramp: nothing to compensate, the uncompensated plan
    wide = _arc_pattern(0.068)
    assert plan_trajectory(wide, rod, PlannerSettings(friction=0.5)).template is not None
    held = plan_trajectory(wide, rod, PlannerSettings(friction=1.0))
    held_plain = plan_trajectory(wide, rod, PlannerSettings(friction=1.0, drag_compensation=False))
    assert held.template is None
    np.testing.assert_array_equal(held.position, held_plain.position)


def test_intuitive_baseline_is_never_compensated():
    rod = rod_description_from_dict(ROD3)
    plan = plan_trajectory(_arc_pattern(0.034), rod, PlannerSettings(method='intuitive', friction=0.5))
    assert plan.template is None


def test_the_template_of_a_mirrored_pattern_is_the_mirrored_template():
    rod = rod_description_from_dict(ROD3)
    P = _arc_pattern(0.034)
    a = plan_trajectory(P, rod, PlannerSettings(friction=0.5))
    b = plan_trajectory(P * [1, -1], rod, PlannerSettings(friction=0.5))
    np.testing.assert_allclose(b.template.xy, a.template.xy * [1, -1], atol=1e-12)
    np.testing.assert_allclose(b.inputs[:, 2], -a.inputs[:, 2], atol=1e-9)


def test_a_template_the_planner_refuses_leaves_the_patterns_own_plan():
    # a 0.3 m rod: 5 cm straight, then an arc of radius 8 cm; with L_gb 4 cm the bend passes the friction check
    # as drawn, the template moved outwards by the predicted drag does not (so near the free end): no template
    rod = rod_description_from_dict({'length': 0.3, 'radius': 0.002, 'L_gb': 0.04, 'friction': 0.5})
    a = np.linspace(0.0, 0.07 / 0.08, 30)
    P = np.vstack([np.column_stack([np.linspace(0, 0.05, 11)[:-1], np.zeros(10)]),
                   np.column_stack([0.05 + 0.08 * np.sin(a), 0.08 * (1 - np.cos(a))])])
    plain = plan_trajectory(P, rod, PlannerSettings(drag_compensation=False))
    plan = plan_trajectory(P, rod, PlannerSettings())
    assert plan.template is None and plan.drag_offset_max() == 0.0
    np.testing.assert_array_equal(plan.position, plain.position)


def _bend_then_arc(lgb=0.034, kb_bend=1.0):
    """A straight lead, a bend of kappa_bar ``kb_bend`` turning right by 90 degrees, a straight, then a wide arc
    (kappa_bar 0.1, which friction 0.5 holds) turning right by about 180 degrees, the steps in kappa_bar smoothed
    over 5 mm: (s, tangent, kappa_bar)."""
    from scipy.ndimage import gaussian_filter1d
    ds = 0.001
    kb = np.concatenate([np.zeros(100), np.full(int(round(0.5 * np.pi * lgb / kb_bend / ds)), kb_bend),
                         np.zeros(80), np.full(int(round(np.pi * lgb / 0.1 / ds)), 0.1)])
    kb = gaussian_filter1d(kb, 5.0, mode='nearest')
    s = ds * np.arange(len(kb))
    theta = -np.concatenate([[0.0], np.cumsum(kb[:-1] / lgb * ds)])            # released sign: right turns
    return s, np.column_stack([np.cos(theta), np.sin(theta)]), kb


def test_shift_term_is_the_translation_by_the_drag_at_the_bend():
    lgb = 0.034
    s, tangent, kb = _bend_then_arc(lgb)
    drag, shift = drag_terms(s, tangent, kb, lgb, 0.5, shift_m=np.inf, start_taper_m=0.0)
    excess, _ = friction_excess(s / lgb, kb, 0.5)
    on_arc = np.flatnonzero((np.abs(kb - 0.1) < 1e-6) & (s > 0.2))
    assert np.all(excess[on_arc[0] - 20:] == 0.0)             # friction holds the wide arc: no drag of its own
    assert np.abs(drag[on_arc[50:]]).max() < 1e-9
    # the bend drags the laid rod inwards, most where the ramp into it adds to the pull (heading +x, the inside -y):
    # Lambda = int excess (-left) ds
    left = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    Lam = np.sum(-excess[:, None] * left * np.diff(s, prepend=0.0)[:, None], axis=0)
    assert np.linalg.norm(Lam) > 1e-3
    assert Lam[1] < -abs(Lam[0])
    # on the arc the template moves against that fixed translation: its normal component, which changes sign
    # along the arc as a translation's does, as large as the translation where the normal is along it
    np.testing.assert_allclose(shift[on_arc], -np.sum(Lam * left[on_arc], axis=1)[:, None] * left[on_arc],
                               atol=1e-9)
    n_shift = np.sum(shift[on_arc] * left[on_arc], axis=1)
    assert n_shift[0] < 0 < n_shift[-1]
    assert n_shift.min() == pytest.approx(-np.linalg.norm(Lam), rel=0.01)
    # a leak length lets it fade: each inward step weighs exp(-(s - s') / 0.2) at s
    _, leaky = drag_terms(s, tangent, kb, lgb, 0.5, shift_m=0.2, start_taper_m=0.0)
    for i in (on_arc[0], on_arc[0] + 200):
        w = np.exp(-(s[i] - s[:i + 1]) / 0.2) * np.diff(s, prepend=0.0)[:i + 1]
        lam_i = np.sum(-excess[:i + 1, None] * left[:i + 1] * w[:, None], axis=0)
        np.testing.assert_allclose(leaky[i], -np.dot(lam_i, left[i]) * left[i], rtol=1e-3, atol=1e-7)
    assert np.linalg.norm(leaky[on_arc[0] + 200]) < 0.5 * np.linalg.norm(shift[on_arc[0] + 200])
    with pytest.raises(ValueError, match='leak'):
        drag_terms(s, tangent, kb, lgb, 0.5, shift_m=0.0)


def test_default_offsets_compensate_the_translation_after_a_bend():
    lgb = 0.034
    s, tangent, kb = _bend_then_arc(lgb)
    off = drag_offsets(s, tangent, kb, lgb, 0.5, start_m=0.05)
    drag_only = drag_offsets(s, tangent, kb, lgb, 0.5, gains=(DRAG_GAIN, 0.0), start_m=0.05)
    on_arc = np.flatnonzero((np.abs(kb - 0.1) < 1e-6) & (s > 0.2))[50:]
    assert np.abs(drag_only[on_arc]).max() < 1e-9              # the one-constant model leaves the arc alone
    terms = drag_terms(s, tangent, kb, lgb, 0.5, DRAG_SHIFT_M, start_m=0.05)
    np.testing.assert_allclose(off, sum(g * t for g, t in zip(DRAG_GAINS, terms)), atol=1e-12)
    assert np.abs(off[on_arc]).max() > 1e-3                   # the translation's compensation: a mm or more
    with pytest.raises(ValueError, match='two finite gains'):
        drag_offsets(s, tangent, kb, lgb, 0.5, gains=(0.3, 0.1, 0.0))


def test_the_drag_within_the_friction_limited_start_moves_the_template_outwards_there():
    # a half circle of radius 8 cm bent from its first point: the friction-limited start replaces 13 cm of it, and
    # the ramp of its curvature asks more of the touch-down point than friction holds; the rod dragged inwards
    # there is laid on from where it was dragged to, so the template moves outwards within the start too (the
    # eleventh round's planner left the start's template on the pattern: at most 0.11 mm off there)
    rod = rod_description_from_dict(ROD3)
    R = 0.08
    a = np.linspace(0.0, np.pi, 300)
    P = np.column_stack([R * np.sin(a), R * (np.cos(a) - 1.0)])            # turning right, centre (0, -R)
    plain = plan_trajectory(P, rod, PlannerSettings(friction=0.5, drag_compensation=False))
    start_m = plain.start_replacement()[0]
    assert start_m > 0.1
    comp = plan_trajectory(P, rod, PlannerSettings(friction=0.5))
    g = comp.drawn_pattern
    k = np.flatnonzero((g.s > 0.03) & (g.s < start_m))
    j = np.array([np.argmin(np.linalg.norm(comp.template.xy - p, axis=1)) for p in g.xy[k]])
    r_template = np.linalg.norm(comp.template.xy[j] - [0.0, -R], axis=1)
    assert (r_template - R).max() > 5e-4                     # outwards: further from the centre, by 0.5 mm or more
    assert (r_template - R).min() > -1e-4
    assert np.linalg.norm(comp.template.xy[0] - P[0]) < 1e-4  # the free end stays at the pattern's first point

