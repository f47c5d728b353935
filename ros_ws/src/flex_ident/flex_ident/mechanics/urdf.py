"""URDF -> serial chain for the variational integrator (xml.etree; no ROS dependency).

Reads links (``<inertial>`` with origin, mass, full inertia tensor) and joints (``revolute``, ``continuous``,
``prismatic``, ``fixed``; ``<origin xyz rpy>``, ``<axis>``, ``<dynamics damping>``). URDF convention: the child
frame of a joint is ``parent * T(xyz) * Rz(yaw) Ry(pitch) Rx(roll) * Rot(axis, q)``.

:func:`serial_chain` extracts the chain ``base_link -> tip_link``: its movable joints (fixed joints merged into the
transforms) and, for each movable joint, the composite rigid body that moves with it (its child link plus everything
rigidly attached, including side branches; movable side joints are frozen at zero). Simulator-specific tags
(``<gazebo>``, ``<transmission>``) are ignored: gravity acts on every link.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .rigid_body import combine_inertias, inertia_matrix, pose_xyz_rpy

MOVABLE = ('revolute', 'continuous', 'prismatic')
SUPPORTED = MOVABLE + ('fixed',)


class UrdfError(ValueError):
    """A URDF that cannot describe the arm (unreadable, missing links/joints or inertials, unsupported joints)."""


@dataclass
class Inertial:
    mass_kg: float
    com_m: np.ndarray           # (3,) in the link frame
    inertia: np.ndarray         # (3, 3) about the com, in link axes [kg m^2]


@dataclass
class Joint:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray          # (4, 4) parent link frame -> joint frame at q = 0
    axis: np.ndarray            # (3,) unit, in the joint frame
    damping: float = 0.0        # viscous [N m s/rad]
    friction: float = 0.0       # Coulomb [N m] (declared by some URDFs; reported, not modelled by default)
    lower: float | None = None
    upper: float | None = None


@dataclass
class Urdf:
    name: str
    path: str
    links: dict[str, Inertial | None]
    joints: dict[str, Joint]
    child_joint: dict[str, Joint] = field(default_factory=dict)      # child link -> joint
    children: dict[str, list[Joint]] = field(default_factory=dict)   # parent link -> joints


@dataclass
class ChainJoint:
    """A movable joint of the serial chain with the rigid body that moves with it."""
    name: str
    type: str                   # 'revolute' | 'continuous' | 'prismatic'
    origin: np.ndarray          # (4, 4) previous movable joint's frame (or base_link) -> this joint frame at q = 0
    axis: np.ndarray            # (3,) unit, in this joint's frame
    damping: float
    friction: float
    mass_kg: float              # composite body in this joint's (moving) frame
    com_m: np.ndarray
    inertia: np.ndarray
    links: list[str]            # links that make up the composite body


@dataclass
class SerialChain:
    base_link: str
    tip_link: str
    joints: list[ChainJoint]
    tip_offset: np.ndarray      # (4, 4) last movable joint frame -> tip_link frame


def _floats(text: str | None, n: int, default, what: str) -> np.ndarray:
    if text is None:
        return np.array(default, dtype=float)
    try:
        values = np.array([float(v) for v in text.split()], dtype=float)
    except ValueError:
        raise UrdfError(f'{what}: cannot read numbers from "{text}"') from None
    if values.shape != (n,) or not np.all(np.isfinite(values)):
        raise UrdfError(f'{what}: expected {n} finite numbers, got "{text}"')
    return values


def _origin(elem, what: str) -> np.ndarray:
    origin = elem.find('origin') if elem is not None else None
    if origin is None:
        return np.eye(4)
    xyz = _floats(origin.get('xyz'), 3, [0, 0, 0], f'{what} origin xyz')
    rpy = _floats(origin.get('rpy'), 3, [0, 0, 0], f'{what} origin rpy')
    return pose_xyz_rpy(xyz, rpy)


def _attr_float(elem, name: str, what: str, default=None):
    text = elem.get(name) if elem is not None else None
    if text is None:
        if default is None:
            raise UrdfError(f'{what}: missing attribute "{name}"')
        return default
    try:
        value = float(text)
    except ValueError:
        raise UrdfError(f'{what}: attribute {name}="{text}" is not a number') from None
    if not np.isfinite(value):
        raise UrdfError(f'{what}: attribute {name}="{text}" is not finite')
    return value


def _parse_inertial(link, path: str) -> Inertial | None:
    inertial = link.find('inertial')
    if inertial is None:
        return None
    name = link.get('name')
    what = f'URDF {path}: link "{name}" <inertial>'
    mass_elem = inertial.find('mass')
    if mass_elem is None:
        raise UrdfError(f'{what} has no <mass>')
    mass = _attr_float(mass_elem, 'value', what + ' mass')
    if mass < 0:
        raise UrdfError(f'{what} has negative mass {mass}')
    i_elem = inertial.find('inertia')
    if i_elem is None:
        raise UrdfError(f'{what} has no <inertia>')
    vals = [_attr_float(i_elem, k, what + ' inertia') for k in ('ixx', 'ixy', 'ixz', 'iyy', 'iyz', 'izz')]
    inertia_local = inertia_matrix(*vals)
    if np.min(np.linalg.eigvalsh(inertia_local)) < -1e-12 * max(1.0, np.abs(inertia_local).max()):
        raise UrdfError(f'{what}: the inertia tensor is not positive semi-definite')
    g = _origin(inertial, what)
    R = g[:3, :3]
    return Inertial(mass, g[:3, 3].copy(), R @ inertia_local @ R.T)


def load_urdf(path: str | Path) -> Urdf:
    """Parse a URDF file. Raises :class:`UrdfError` naming the problem."""
    path = str(path)
    if not Path(path).is_file():
        raise UrdfError(f'URDF file {path} does not exist')
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise UrdfError(f'URDF {path} is not valid XML: {exc}') from None
    if root.tag != 'robot':
        raise UrdfError(f'URDF {path}: root element is <{root.tag}>, expected <robot>')
    links = {}
    for link in root.findall('link'):
        name = link.get('name')
        if not name:
            raise UrdfError(f'URDF {path}: a <link> has no name')
        links[name] = _parse_inertial(link, path)
    joints = {}
    for j in root.findall('joint'):
        name = j.get('name')
        jtype = j.get('type')
        what = f'URDF {path}: joint "{name}"'
        if not name:
            raise UrdfError(f'URDF {path}: a <joint> has no name')
        parent = j.find('parent')
        child = j.find('child')
        if parent is None or child is None or not parent.get('link') or not child.get('link'):
            raise UrdfError(f'{what} needs <parent link=...> and <child link=...>')
        axis = _floats(j.find('axis').get('xyz') if j.find('axis') is not None else None, 3, [1, 0, 0],
                       what + ' axis')
        if jtype in MOVABLE:
            norm = np.linalg.norm(axis)
            if norm < 1e-12:
                raise UrdfError(f'{what} has a zero axis')
            axis = axis / norm
        dyn = j.find('dynamics')
        limit = j.find('limit')
        joints[name] = Joint(
            name=name, type=jtype, parent=parent.get('link'), child=child.get('link'), origin=_origin(j, what),
            axis=axis, damping=_attr_float(dyn, 'damping', what, 0.0), friction=_attr_float(dyn, 'friction', what, 0.0),
            lower=_attr_float(limit, 'lower', what, 0.0) if limit is not None and limit.get('lower') else None,
            upper=_attr_float(limit, 'upper', what, 0.0) if limit is not None and limit.get('upper') else None)
    urdf = Urdf(name=root.get('name', ''), path=path, links=links, joints=joints)
    for j in joints.values():
        for link in (j.parent, j.child):
            if link not in links:
                raise UrdfError(f'URDF {path}: joint "{j.name}" refers to unknown link "{link}"')
        if j.child in urdf.child_joint:
            raise UrdfError(f'URDF {path}: link "{j.child}" is the child of two joints')
        urdf.child_joint[j.child] = j
        urdf.children.setdefault(j.parent, []).append(j)
    return urdf


def serial_chain(urdf: Urdf, base_link: str, tip_link: str) -> SerialChain:
    """The chain of joints from ``base_link`` to ``tip_link`` with composite bodies per movable joint."""
    for link, role in ((base_link, 'base_link'), (tip_link, 'tip_link')):
        if link not in urdf.links:
            raise UrdfError(f'{role} "{link}" is not a link of URDF {urdf.path} '
                            f'(links: {", ".join(sorted(urdf.links))})')
    path = []
    link = tip_link
    while link != base_link:
        joint = urdf.child_joint.get(link)
        if joint is None:
            raise UrdfError(f'tip_link "{tip_link}" is not below base_link "{base_link}" in URDF {urdf.path}')
        path.append(joint)
        link = joint.parent
    path.reverse()
    for joint in path:
        if joint.type not in SUPPORTED:
            raise UrdfError(f'joint "{joint.name}" of URDF {urdf.path} has type "{joint.type}"; '
                            f'supported: {", ".join(SUPPORTED)}')
    chain_joint_names = {j.name for j in path}
    movable = [j for j in path if j.type in MOVABLE]
    if not movable:
        raise UrdfError(f'the chain {base_link} -> {tip_link} in URDF {urdf.path} has no movable joint')

    # frame of each chain link relative to the movable joint frame it moves with (index into movable, -1 = base)
    chain_out = []
    offset = np.eye(4)
    owner = -1
    link_owner = {base_link: (-1, np.eye(4))}
    for joint in path:
        if joint.type in MOVABLE:
            chain_out.append((joint, offset @ joint.origin))
            owner = len(chain_out) - 1
            offset = np.eye(4)
        else:
            offset = offset @ joint.origin
        link_owner[joint.child] = (owner, offset.copy())
    tip_offset = offset

    # composite bodies: every link rigidly attached to a movable joint's child (side branches frozen at 0)
    parts = [[] for _ in movable]
    part_links = [[] for _ in movable]
    visited = [[] for _ in movable]

    def attach(link_name, k, g_link):
        visited[k].append(link_name)
        inertial = urdf.links[link_name]
        if inertial is not None:
            R = g_link[:3, :3]
            parts[k].append((inertial.mass_kg, g_link[:3, 3] + R @ inertial.com_m, R @ inertial.inertia @ R.T))
            part_links[k].append(link_name)
        for j in urdf.children.get(link_name, []):
            if j.name in chain_joint_names and j.type in MOVABLE:
                continue                      # the next body of the chain
            if j.name in chain_joint_names:
                attach(j.child, k, link_owner[j.child][1])
            else:
                attach(j.child, k, g_link @ j.origin)

    for k, joint in enumerate(movable):
        attach(joint.child, k, np.eye(4))
    missing = [f'{joint.name} ({", ".join(visited[k])})' for k, joint in enumerate(movable) if not part_links[k]]
    if missing:
        raise UrdfError(f'URDF {urdf.path}: no <inertial> on the links moved by joint(s) {"; ".join(missing)}; '
                        'the dynamics needs the mass and inertia tensor of every moving link')
    out = []
    for k, (joint, origin) in enumerate(chain_out):
        mass, com, inertia = combine_inertias(parts[k])
        out.append(ChainJoint(name=joint.name, type=joint.type, origin=origin, axis=joint.axis.copy(),
                              damping=joint.damping, friction=joint.friction, mass_kg=mass, com_m=com,
                              inertia=inertia, links=part_links[k]))
    return SerialChain(base_link=base_link, tip_link=tip_link, joints=out, tip_offset=tip_offset)
