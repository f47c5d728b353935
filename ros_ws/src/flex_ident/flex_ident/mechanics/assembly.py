"""Experiment -> :class:`MechanicalModel`: the arm from its URDF, then the contract loop (or nothing).

Configuration order (CONTRACTS.md): the arm joints in ``arm.joints`` order, then (theta_1, phi_1, ...) of the left
branch, then of the right branch. Coefficients: ``k_theta``, ``k_phi`` (loop), ``damping_<joint>`` (the URDF's
declared viscous damping of each arm joint, fixed unless identification frees it).
"""
from __future__ import annotations

import numpy as np

from .experiment import Experiment, ExperimentError
from .loop_geometry import K_PHI, K_THETA, add_contract_loop
from .model import MechanicalModel, ModelBuilder, PRISMATIC, REVOLUTE, ViscousDamping
from .urdf import SerialChain, UrdfError, load_urdf, serial_chain


def add_serial_arm(builder: ModelBuilder, chain: SerialChain, joint_order: list[str]) -> list[int]:
    """Add the chain's movable joints as coordinates in ``joint_order``; inputs, damping, tip frame.

    Returns the coordinate index of each chain joint (chain order).
    """
    chain_names = [j.name for j in chain.joints]
    index = {name: builder.add_coordinate(name, -1, np.eye(4), [0, 0, 1]) for name in joint_order}
    coords = []
    for k, joint in enumerate(chain.joints):
        i = index[joint.name]
        parent = index[chain_names[k - 1]] if k > 0 else -1
        builder.set_parent(i, parent, joint.origin)
        builder.axis[i] = joint.axis / np.linalg.norm(joint.axis)
        builder.jtype[i] = PRISMATIC if joint.type == 'prismatic' else REVOLUTE
        builder.add_body(i, joint.mass_kg, joint.com_m, joint.inertia)
        coords.append(i)
    for name in joint_order:
        i = index[name]
        joint = chain.joints[chain_names.index(name)]
        builder.add_input(i)
        c = builder.add_coefficient(f'damping_{name}', joint.damping,
                                    f'viscous damping of arm joint {name} (declared in the URDF)', 'N m s/rad')
        builder.add_term(ViscousDamping(i, c))
        builder.measured.append(i)
    builder.add_frame('tip', coords[-1], chain.tip_offset)
    return coords


def check_joint_list(chain: SerialChain, joints: list[str], urdf, where: str):
    chain_names = [j.name for j in chain.joints]
    unknown = [j for j in joints if j not in urdf.joints]
    if unknown:
        raise ExperimentError(f'{where}: arm.joints {unknown} are not joints of URDF {urdf.path}')
    off_chain = [j for j in joints if j not in chain_names and urdf.joints[j].type != 'fixed']
    if off_chain:
        raise ExperimentError(f'{where}: arm.joints {off_chain} are not on the chain {chain.base_link} -> '
                              f'{chain.tip_link} (its movable joints: {chain_names})')
    fixed = [j for j in joints if j not in chain_names]
    if fixed:
        raise ExperimentError(f'{where}: arm.joints {fixed} are fixed joints; list only movable joints '
                              f'({chain_names})')
    missing = [j for j in chain_names if j not in joints]
    if missing:
        raise ExperimentError(f'{where}: the movable joint(s) {missing} of the chain {chain.base_link} -> '
                              f'{chain.tip_link} are missing from arm.joints')


def build_model(experiment: Experiment, coefficient_values: dict | None = None) -> MechanicalModel:
    """The model of an experiment. Coefficients take ``coefficient_values`` (name -> value), then the identify
    section's initial values, then their defaults. Raises ExperimentError/UrdfError (ValueErrors) on bad input."""
    where = experiment.path
    try:
        urdf = load_urdf(experiment.arm.urdf_path)
        chain = serial_chain(urdf, experiment.arm.base_link, experiment.arm.tip_link)
    except UrdfError as exc:
        raise UrdfError(f'{where}: {exc}') from None
    check_joint_list(chain, list(experiment.arm.joints), urdf, where)
    builder = ModelBuilder(gravity=experiment.arm.gravity_mps2)
    coords = add_serial_arm(builder, chain, list(experiment.arm.joints))
    builder.description.update({'urdf': experiment.arm.urdf_path, 'arm_joints': list(experiment.arm.joints),
                                'object': 'none'})
    values = {p.name: p.initial for p in experiment.identify.parameters}
    values.update(coefficient_values or {})
    loop = experiment.object
    if loop is not None:
        add_contract_loop(builder, loop.links, loop.radius_m, loop.mass_kg, loop.tube_radius_m,
                          grasp_coord=coords[-1], grasp_offset=chain.tip_offset @ loop.grasp.matrix(),
                          clamp_pose=loop.clamp.matrix(),
                          k_theta=values.get(K_THETA, 1.0), k_phi=values.get(K_PHI, 1.0))
        builder.add_frame('ee', coords[-1], chain.tip_offset @ loop.grasp.matrix())
    else:
        builder.add_frame('ee', coords[-1], chain.tip_offset)
    model = builder.build()
    known = model.coef_names
    unknown = [p.name for p in experiment.identify.parameters if p.name not in known]
    if unknown:
        raise ExperimentError(f'{where}: identify.parameters {unknown} are not parameters of this model '
                              f'(known: {", ".join(known)})')
    for name, value in values.items():
        if name in known:
            i = model.coef_index(name)
            c = model.coefficients[i]
            model.coefficients[i] = type(c)(c.name, float(value), c.description, c.unit)
    return model
