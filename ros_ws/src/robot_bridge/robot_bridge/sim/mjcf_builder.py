"""MJCF (MuJoCo XML) for a URDF arm holding the contract's closed flexible loop, built from the experiment.

Arm: one body per URDF link below ``base_link`` (the world frame), placed by the URDF joint origins; a hinge (or
slide) for each joint listed in ``arm.joints`` with the URDF axis and ``<dynamics damping>`` as MuJoCo joint damping;
movable joints not listed are locked at 0; URDF inertials as full inertia tensors; a motor on every listed joint.
Loop (CONTRACTS.md section 2): two branches of N/2 solid-cylinder links leave the grasp frame G; each loop joint is
two hinges in one body, about the link frame's y then z axis, so that the body frame is
parent . T . Ry(theta) . Rz(phi) (MuJoCo composes the joints of a body in order); springs are MuJoCo joint
``stiffness`` with ``springref`` 0; each branch end frame E = L_{N/2} . T(l, 0, 0) is a site welded (6 constraints)
to its clamp site (E_left = C Ry(pi/N - pi), E_right = C Ry(-pi/N)).
Contacts are disabled: nothing touches anything in this experiment.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

from .experiment import ExperimentSpec
from .transforms import matrix_quat, rot_y, transform
from .urdf_arm import UrdfRobot, parse_urdf

LOOP_SIDES = ('left', 'right')


@dataclass
class Numerics:
    """Integration and constraint settings.

    weld_solref / weld_solimp: MuJoCo soft-constraint parameters of the clamp welds (time constant [s], damping
    ratio; impedance). The time constant must stay >= 2 timesteps for stability.
    """
    timestep_s: float = 1e-3
    integrator: str = 'RK4'
    weld_solref: tuple[float, float] = (0.002, 1.0)
    weld_solimp: tuple[float, ...] = (0.9999, 0.9999, 0.001, 0.5, 2.0)
    solver_iterations: int = 200
    solver_tolerance: float = 1e-12


@dataclass
class PassiveEffects:
    """Physical effects beyond the declared model (all zero: exactly the contract's model).

    loop_damping_nms: viscous damping on every loop joint [N m s/rad]; arm_viscous_nms: viscous damping added to
    the URDF damping of every arm joint [N m s/rad] (scalar or one per joint); arm_coulomb_nm: Coulomb friction on
    every arm joint [N m] (MuJoCo frictionloss).
    """
    loop_damping_nms: float = 0.0
    arm_viscous_nms: float | list[float] = 0.0
    arm_coulomb_nm: float | list[float] = 0.0


@dataclass
class BuiltModel:
    """The MJCF text and the names the simulator needs to find things in the compiled model."""
    xml: str
    arm_joints: list[str]
    loop_joints: list[str] = field(default_factory=list)      # contract order: left (theta, phi)..., right...
    locked_joints: list[str] = field(default_factory=list)    # movable URDF joints not in arm.joints
    urdf: UrdfRobot | None = None


def _fmt(values) -> str:
    return ' '.join(repr(float(v)) for v in np.ravel(values))   # shortest round-trip text


def _set_pose(elem, tf: np.ndarray):
    elem.set('pos', _fmt(tf[:3, 3]))
    elem.set('quat', _fmt(matrix_quat(tf[:3, :3])))


def _per_joint(value, n: int, what: str) -> np.ndarray:
    arr = np.broadcast_to(np.asarray(value, dtype=float), (n,)) if np.ndim(value) == 0 else np.asarray(value, float)
    if arr.shape != (n,):
        raise ValueError(f'{what} needs 1 or {n} values, got {len(arr)}')
    return np.array(arr)


def cylinder_link_inertia(mass_kg: float, radius_m: float, length_m: float) -> np.ndarray:
    """Principal moments [kg m^2] of a solid cylinder about its centre, x along the axis: (Ixx, Iyy, Izz)."""
    axial = 0.5 * mass_kg * radius_m ** 2
    transverse = mass_kg * (3.0 * radius_m ** 2 + length_m ** 2) / 12.0
    return np.array([axial, transverse, transverse])


def add_loop_link(parent, name: str, frame: np.ndarray, length_m: float, mass_kg: float, tube_radius_m: float,
                  k_theta: float, k_phi: float, damping_nms: float) -> ET.Element:
    """One loop link as a child body of ``parent``: frame = parent . frame . Ry(theta) . Rz(phi).

    Joints ``<name>_theta`` (hinge about y) then ``<name>_phi`` (hinge about z), springs with rest angle 0; a solid
    cylinder along +x from the joint to (length, 0, 0), its inertia given explicitly.
    """
    body = ET.SubElement(parent, 'body', name=name)
    _set_pose(body, frame)
    for suffix, axis, k in (('theta', '0 1 0', k_theta), ('phi', '0 0 1', k_phi)):
        ET.SubElement(body, 'joint', name=f'{name}_{suffix}', type='hinge', axis=axis, pos='0 0 0',
                      stiffness=_fmt([k]), springref='0', damping=_fmt([damping_nms]), armature='0')
    ET.SubElement(body, 'inertial', pos=_fmt([length_m / 2, 0, 0]), mass=_fmt([mass_kg]),
                  diaginertia=_fmt(cylinder_link_inertia(mass_kg, tube_radius_m, length_m)))
    ET.SubElement(body, 'geom', type='cylinder', fromto=_fmt([0, 0, 0, length_m, 0, 0]),
                  size=_fmt([tube_radius_m]), contype='0', conaffinity='0', rgba='0.2 0.2 0.2 1')
    return body


def _add_arm_subtree(parent_elem, robot: UrdfRobot, link: str, listed: set, effects_damping: dict,
                     effects_coulomb: dict, locked: list, arm_joint_order: list):
    for joint in robot.child_joints(link):
        body = ET.SubElement(parent_elem, 'body', name=joint.child)
        _set_pose(body, joint.origin)
        if joint.movable and joint.name in listed:
            jtype = 'slide' if joint.type == 'prismatic' else 'hinge'
            attrs = dict(name=joint.name, type=jtype, axis=_fmt(joint.axis), pos='0 0 0',
                         damping=_fmt([joint.damping + effects_damping[joint.name]]),
                         frictionloss=_fmt([joint.friction + effects_coulomb[joint.name]]), armature='0',
                         limited='false')
            ET.SubElement(body, 'joint', **attrs)
            arm_joint_order.append(joint.name)
        elif joint.movable:
            locked.append(joint.name)
        inertial = robot.inertials.get(joint.child)
        if inertial is not None and inertial.mass_kg > 0:
            rot = inertial.origin[:3, :3]
            i = rot @ inertial.inertia @ rot.T   # about the CoM, in the link (body) axes
            ET.SubElement(body, 'inertial', pos=_fmt(inertial.origin[:3, 3]), mass=_fmt([inertial.mass_kg]),
                          fullinertia=_fmt([i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]))
        _add_arm_subtree(body, robot, joint.child, listed, effects_damping, effects_coulomb, locked,
                         arm_joint_order)


def build_mjcf(exp: ExperimentSpec, k_theta: float = 1.0, k_phi: float = 1.0,
               effects: PassiveEffects | None = None, numerics: Numerics | None = None,
               with_object: bool = True) -> BuiltModel:
    """MJCF of the arm (+ the loop if the experiment has one and ``with_object``). See the module docstring."""
    effects = effects or PassiveEffects()
    numerics = numerics or Numerics()
    robot = parse_urdf(exp.arm.urdf_path)
    chain = robot.chain(exp.arm.base_link, exp.arm.tip_link)
    movable_in_chain = {j.name for j in chain if j.movable}
    for name in exp.arm.joints:
        if name not in robot.joints:
            raise ValueError(f"arm.joints names '{name}', which URDF '{robot.name}' does not have")
        if name not in movable_in_chain:
            raise ValueError(f"arm joint '{name}' is not a movable joint between "
                             f"'{exp.arm.base_link}' and '{exp.arm.tip_link}'")
    n_arm = len(exp.arm.joints)
    damping = dict(zip(exp.arm.joints, _per_joint(effects.arm_viscous_nms, n_arm, 'arm_viscous_nms')))
    coulomb = dict(zip(exp.arm.joints, _per_joint(effects.arm_coulomb_nm, n_arm, 'arm_coulomb_nm')))

    root = ET.Element('mujoco', model=f'{robot.name}_loop')
    ET.SubElement(root, 'compiler', angle='radian', inertiafromgeom='false', autolimits='true')
    option = ET.SubElement(root, 'option', timestep=_fmt([numerics.timestep_s]), integrator=numerics.integrator,
                           gravity=_fmt(exp.gravity_m_s2), iterations=str(numerics.solver_iterations),
                           tolerance=_fmt([numerics.solver_tolerance]), solver='Newton', cone='pyramidal')
    ET.SubElement(option, 'flag', contact='disable', energy='enable')
    world = ET.SubElement(root, 'worldbody')
    locked, arm_order = [], []
    _add_arm_subtree(world, robot, exp.arm.base_link, set(exp.arm.joints), damping, coulomb, locked, arm_order)
    built = BuiltModel(xml='', arm_joints=list(exp.arm.joints), locked_joints=locked, urdf=robot)

    tip_body = world.find(f".//body[@name='{exp.arm.tip_link}']")
    if tip_body is None:   # the tip is the base itself (degenerate)
        raise ValueError(f"tip_link '{exp.arm.tip_link}' must be below base_link '{exp.arm.base_link}'")
    loop = exp.loop if with_object else None
    grasp = loop.grasp if loop is not None else np.eye(4)
    site = ET.SubElement(tip_body, 'site', name='grasp', size='0.01')
    _set_pose(site, grasp)

    if loop is not None:
        n, l_m = loop.links, loop.link_length_m
        first = {'left': rot_y(-np.pi / n), 'right': rot_y(np.pi + np.pi / n)}
        step = {'left': rot_y(-2 * np.pi / n), 'right': rot_y(2 * np.pi / n)}
        for side in LOOP_SIDES:
            parent, frame = tip_body, grasp @ transform(first[side])
            for k in range(1, n // 2 + 1):
                name = f'loop_{side}_{k}'
                parent = add_loop_link(parent, name, frame, l_m, loop.link_mass_kg, loop.tube_radius_m,
                                       k_theta, k_phi, effects.loop_damping_nms)
                built.loop_joints += [f'{name}_theta', f'{name}_phi']
                frame = transform(step[side], (l_m, 0.0, 0.0))
            ET.SubElement(parent, 'site', name=f'loop_{side}_end', pos=_fmt([l_m, 0, 0]), size='0.01')
        for side, target in zip(LOOP_SIDES, loop.end_targets()):
            clamp_site = ET.SubElement(world, 'site', name=f'clamp_{side}', size='0.01')
            _set_pose(clamp_site, target)
        equality = ET.SubElement(root, 'equality')
        for side in LOOP_SIDES:
            ET.SubElement(equality, 'weld', name=f'clamp_{side}', site1=f'loop_{side}_end', site2=f'clamp_{side}',
                          solref=_fmt(numerics.weld_solref), solimp=_fmt(numerics.weld_solimp))

    actuators = ET.SubElement(root, 'actuator')
    for name in arm_order:
        ET.SubElement(actuators, 'motor', name=f'motor_{name}', joint=name, gear='1')
    ET.indent(root)
    built.xml = ET.tostring(root, encoding='unicode')
    built.arm_joints = arm_order   # URDF tree order (also the qpos order)
    return built
