"""The drag at bends: the contact-force table, the friction demand and excess, the planner's compensation."""
import numpy as np
import pytest

from rod_deploy.planning.bend_drag import (CONTACT_FY, CONTACT_FZ, CONTACT_KAPPA_BAR, DRAG_GAIN, contact_force_table,
                                           drag_offsets, friction_demand, friction_excess)
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
    off = drag_offsets(s, tangent, kb, lgb, 0.5)
    assert np.all(off[:, 0] == 0.0)
    assert np.all(np.abs(off[s < 0.03, 1]) < 1e-4)            # tapered in from the free end
    # right turn (kappa_bar > 0, released sign): the laid rod is dragged right, the template moves left (+y)
    assert np.sign(off[-1, 1]) == turn
    assert abs(off[-1, 1]) == pytest.approx(DRAG_GAIN * lgb * (0.5665 - 0.5 * 0.6125), rel=0.02)


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
    assert 0.002 < d.max() < 0.008                            # the bend moved by about the predicted drag
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
