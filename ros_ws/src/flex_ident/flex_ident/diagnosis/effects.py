"""Candidate effects the declared model may lack, as named coefficients and model terms (CONTRACTS.md section 2:
nothing but the URDF inertias and damping and the loop springs is declared).

Each candidate is what a robotics engineer checks first when a model does not fit a recording:

| key             | words in the report                     | coefficients (model terms)                               |
|-----------------|-----------------------------------------|----------------------------------------------------------|
| loop_damping    | loop joint viscous damping              | c_loop [N m s/rad] (ViscousDamping on every loop angle)  |
| arm_viscous     | arm joint viscous friction (extra)      | c_arm [N m s/rad] (ViscousDamping on every arm joint)    |
| arm_viscous_per_joint | the same, one value per joint     | c_arm_<joint> [N m s/rad]                                |
| arm_coulomb     | arm joint Coulomb friction              | f_arm [N m] (smoothed CoulombFriction on every arm joint)|
| arm_coulomb_per_joint | the same, one value per joint     | f_arm_<joint> [N m]                                      |
| torque_bias     | torque sensor bias                      | b_<joint> [N m] per arm joint (ConstantForce = -bias)    |
| torque_gain     | torque sensor gain                      | torque_input_scale = 1 / gain (the inputs' gain)         |
| time_offset     | measurement delay (torque vs. encoders) | delay_s [s]: efforts used as tau_meas(t + delay_s)       |
| loop_rest_angle | rest-angle offset of the object         | rest_<theta|phi>_<left|right> [rad]: the loop springs'   |
|                 |                                         | rest angle, per branch and bending direction (Spring)    |
| loop_mass       | loop mass error                         | dm_loop: every loop link's mass and inertia x (1 + dm)   |
| payload         | payload at the gripper                  | payload_kg [kg]: a point mass at the grasp frame 'ee'    |

A per-joint friction *replaces* its shared variant when both are considered: the closed loop tests the per-joint
values against the shared one (one value against seven, BIC), so the statistics decide between them.

Every coefficient has a *null value* (0, or 1 for the gain) at which the model is the declared one, so the score at
the null is the first-order evidence for the effect. ``time_offset`` is no model term: it shifts the measured
torques in time (see :class:`~.closed_loop.OuterParameterProblem`); a positive offset means the torque sensors lag the
encoders, a negative one that the encoders lag the torque sensors (the two are indistinguishable up to a shift of
the whole recording, which starts at rest).

``loop_mass`` and ``payload`` are no model terms either: the bodies' masses are constants of the compiled kernel, so
these *outer parameters* rebuild the model (:func:`apply_outer_parameters`) and their Jacobian columns are central
differences through the whole pipeline, like the time offset's (the model is linear in the masses, so the
difference is accurate; checked against a step ten times finer in the tests). With k_theta and k_phi free, the loop's
mass only shows through the loop's load on the arm: scaling the loop's mass and its stiffnesses together leaves its
shape and motion unchanged for a given arm motion, the torques the arm needs do not.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from ..mechanics.model import Coefficient, ConstantForce, CoulombFriction, Spring, ViscousDamping
from ..mechanics.rigid_body import combine_inertias

#: smoothing velocity of the Coulomb friction model [rad/s]
COULOMB_VELOCITY_SCALE = 0.02
DELAY_PARAMETER = 'delay_s'
LOOP_MASS_PARAMETER = 'dm_loop'
PAYLOAD_PARAMETER = 'payload_kg'
#: parameters that are not model coefficients, in the order they come last in a free-parameter list, with the step of
#: their central-difference Jacobian column (delay [s], relative loop mass [-], payload [kg])
OUTER_PARAMETERS = {LOOP_MASS_PARAMETER: 0.01, PAYLOAD_PARAMETER: 0.01, DELAY_PARAMETER: 0.002}


@dataclass(frozen=True)
class Effect:
    key: str
    name: str                   # words a robotics engineer understands
    coefficients: tuple         # coefficient names (model coefficients, or one of OUTER_PARAMETERS)
    null: tuple                 # value of each coefficient at which the effect is absent
    lower: tuple
    upper: tuple
    one_sided: bool             # a physical effect with a sign (damping, friction): the score only counts >= 0
    replaces: str = ''          # key of the shared variant this per-joint effect refines (it starts at its value)

    @property
    def size(self) -> int:
        return len(self.coefficients)


def loop_coords(model) -> np.ndarray:
    measured = set(int(i) for i in model.measured_coords)
    return np.array([i for i in range(model.n) if i not in measured], dtype=np.int64)


def arm_joint_names(model) -> list:
    return [model.coord_names[i] for i in model.measured_coords]


def candidate_effects(model) -> list[Effect]:
    """The candidate effects for a model built from an experiment (arm + loop, or arm only)."""
    out = []
    if len(loop_coords(model)):
        out.append(Effect('loop_damping', 'loop joint viscous damping', ('c_loop',), (0.0,), (0.0,), (100.0,), True))
    joints = arm_joint_names(model)
    n = len(joints)
    out.append(Effect('arm_viscous', 'arm joint viscous friction (in addition to the URDF damping)', ('c_arm',),
                      (0.0,), (0.0,), (100.0,), True))
    out.append(Effect('arm_viscous_per_joint',
                      'arm joint viscous friction, per joint (in addition to the URDF damping)',
                      tuple(f'c_arm_{j}' for j in joints), (0.0,) * n, (0.0,) * n, (100.0,) * n, True, 'arm_viscous'))
    out.append(Effect('arm_coulomb', 'arm joint Coulomb friction', ('f_arm',), (0.0,), (0.0,), (100.0,), True))
    out.append(Effect('arm_coulomb_per_joint', 'arm joint Coulomb friction, per joint',
                      tuple(f'f_arm_{j}' for j in joints), (0.0,) * n, (0.0,) * n, (100.0,) * n, True, 'arm_coulomb'))
    # the object's declared mass and a payload come before the sensor's bias and gain: when the data cannot tell
    # them apart (they all load the arm mostly through gravity), the closed loop adds the first (closed_loop._choose)
    if len(loop_coords(model)):
        out.append(Effect('loop_mass', 'loop mass error (the object is heavier or lighter than declared)',
                          (LOOP_MASS_PARAMETER,), (0.0,), (-0.8,), (4.0,), False))
    out.append(Effect('payload', 'payload at the gripper (an undeclared mass at the grasp frame)', (PAYLOAD_PARAMETER,),
                      (0.0,), (0.0,), (20.0,), True))
    out.append(Effect('torque_bias', 'torque sensor bias (per joint)', tuple(f'b_{j}' for j in joints),
                      (0.0,) * len(joints), (-np.inf,) * len(joints), (np.inf,) * len(joints), False))
    out.append(Effect('torque_gain', 'torque sensor gain', ('torque_input_scale',), (1.0,), (0.2,), (5.0,), False))
    out.append(Effect('time_offset', 'measurement delay between torque sensors and joint encoders',
                      (DELAY_PARAMETER,), (0.0,), (-0.1,), (0.1,), False))
    groups = rest_angle_groups(model)
    if groups:
        out.append(Effect('loop_rest_angle', 'rest-angle offset of the object (its unloaded shape is not the declared '
                          'one)', tuple(groups), (0.0,) * len(groups), (-0.5,) * len(groups), (0.5,) * len(groups),
                          False))
    return out


def rest_angle_groups(model) -> dict:
    """Loop springs grouped by branch and bending direction: {'rest_theta_left': [term index, ...], ...}."""
    names = model.coef_names
    kinds = {names.index(k): k[2:] for k in ('k_theta', 'k_phi') if k in names}
    groups = {}
    for t_index, term in enumerate(model.terms):
        if isinstance(term, Spring) and term.coef in kinds:
            name = model.coord_names[term.coord]
            side = 'left' if '_left_' in name else 'right' if '_right_' in name else ''
            key = f'rest_{kinds[term.coef]}' + (f'_{side}' if side else '')
            groups.setdefault(key, []).append(t_index)
    return groups


def with_effect(model, effect: Effect):
    """A copy of ``model`` with the effect's coefficients (at their null values) and terms."""
    n0 = len(model.coefficients)
    arm = [int(i) for i in model.measured_coords]
    if effect.key in ('time_offset', 'loop_mass', 'payload'):
        return model            # outer parameters (apply_outer_parameters), no model term
    if effect.key == 'loop_damping':
        coefs = [Coefficient('c_loop', 0.0, 'viscous damping of every loop joint', 'N m s/rad')]
        terms = [ViscousDamping(int(i), n0) for i in loop_coords(model)]
    elif effect.key == 'arm_viscous':
        coefs = [Coefficient('c_arm', 0.0, 'viscous friction of every arm joint beyond the URDF damping',
                             'N m s/rad')]
        terms = [ViscousDamping(i, n0) for i in arm]
    elif effect.key == 'arm_coulomb':
        coefs = [Coefficient('f_arm', 0.0, 'Coulomb friction torque of every arm joint', 'N m')]
        terms = [CoulombFriction(i, n0, COULOMB_VELOCITY_SCALE) for i in arm]
    elif effect.key == 'arm_viscous_per_joint':
        coefs = [Coefficient(c, 0.0, f'viscous friction of {c[6:]} beyond the URDF damping', 'N m s/rad')
                 for c in effect.coefficients]
        terms = [ViscousDamping(i, n0 + k) for k, i in enumerate(arm)]
    elif effect.key == 'arm_coulomb_per_joint':
        coefs = [Coefficient(c, 0.0, f'Coulomb friction torque of {c[6:]}', 'N m') for c in effect.coefficients]
        terms = [CoulombFriction(i, n0 + k, COULOMB_VELOCITY_SCALE) for k, i in enumerate(arm)]
    elif effect.key == 'loop_rest_angle':
        coefs = [Coefficient(c, 0.0, f'rest-angle offset of the loop springs ({c[5:].replace("_", ", ")})', 'rad')
                 for c in effect.coefficients]
        out = model.extended(coefs, [])
        out.terms = list(out.terms)
        for name, indices in rest_angle_groups(model).items():
            for t_index in indices:
                s = out.terms[t_index]
                out.terms[t_index] = Spring(s.coord, s.coef, s.rest, n0 + effect.coefficients.index(name))
        return out
    elif effect.key == 'torque_bias':
        names = effect.coefficients
        coefs = [Coefficient(c, 0.0, f'torque sensor bias of {c[2:]} (reads this much too high)', 'N m')
                 for c in names]
        # the sensor reads tau + b: the joint gets the reading minus b
        terms = []
        for k, i in enumerate(arm):
            terms.append(ConstantForce(i, n0 + k))
    elif effect.key == 'torque_gain':
        coefs = [Coefficient('torque_input_scale', 1.0, 'applied torque per unit of torque reading (1 / sensor gain)',
                             '')]
        terms = []
    else:
        raise KeyError(effect.key)
    out = model.extended(coefs, terms)
    if effect.key == 'torque_gain':
        out = copy.copy(out)
        out.input_gain_coef = np.full_like(model.input_gain_coef, n0)
        out._kernel = None
    return out


def apply_outer_parameters(model, values: dict):
    """``model`` with the outer parameters' mass changes (a copy when any is non-zero; time shifts act on the data):
    every loop link's mass and inertia x (1 + dm_loop) (same centres of mass), and a point mass payload_kg at the grasp
    frame 'ee' combined into the body of its coordinate. A small negative payload (a finite-difference step at the
    null value) stays a valid model: the link keeps a positive mass."""
    dm = float(values.get(LOOP_MASS_PARAMETER, 0.0))
    payload = float(values.get(PAYLOAD_PARAMETER, 0.0))
    if dm == 0.0 and payload == 0.0:
        return model
    out = copy.copy(model)
    out.body_mass, out.body_com, out.body_inertia = (model.body_mass.copy(), model.body_com.copy(),
                                                     model.body_inertia.copy())
    out._kernel = None
    if dm != 0.0:
        loop = loop_coords(model)
        out.body_mass[loop] *= 1.0 + dm
        out.body_inertia[loop] *= 1.0 + dm
    if payload != 0.0:
        coord, offset = model.frames['ee']
        m, c, i = combine_inertias([(out.body_mass[coord], out.body_com[coord], out.body_inertia[coord]),
                                    (payload, offset[:3, 3], np.zeros((3, 3)))])
        if m <= 0.0:
            raise ValueError(f'a payload of {payload:g} kg leaves no mass on the grasping link')
        out.body_mass[coord], out.body_com[coord], out.body_inertia[coord] = m, c, i
    return out


def reported_parameters(effect: Effect, values) -> dict:
    """The effect's parameters in the units an engineer reads (bias as the sensor's offset, gain as the sensor's)."""
    values = [float(v) for v in values]
    if effect.key == 'torque_bias':
        # ConstantForce coefficient = -bias
        return {name: -v for name, v in zip(effect.coefficients, values)}
    if effect.key == 'torque_gain':
        return {'torque_sensor_gain': 1.0 / values[0]}
    if effect.key == 'loop_mass':
        return {LOOP_MASS_PARAMETER: values[0], 'loop_mass_scale': 1.0 + values[0]}
    return dict(zip(effect.coefficients, values))


def describe(effect: Effect, values) -> str:
    p = reported_parameters(effect, values)
    if effect.key == 'time_offset':
        d = p[DELAY_PARAMETER]
        return (f'torque sensors lag the joint encoders by {1e3 * d:.1f} ms' if d >= 0
                else f'joint encoders lag the torque sensors by {-1e3 * d:.1f} ms')
    if effect.key == 'loop_mass':
        d = p[LOOP_MASS_PARAMETER]
        return (f'the loop is {100 * abs(d):.1f} % {"heavier" if d >= 0 else "lighter"} than declared '
                f'({LOOP_MASS_PARAMETER} = {d:.4g})')
    return ', '.join(f'{k} = {v:.4g}' for k, v in p.items())
