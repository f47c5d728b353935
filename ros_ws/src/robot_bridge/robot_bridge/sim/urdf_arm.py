"""A URDF arm as plain data (xml.etree): links with their inertials, joints with origin, axis, limits and dynamics.

Only what a rigid-body simulator needs: no meshes, visuals, collisions or transmissions. Simulator-specific tags
(e.g. Gazebo's ``<gravity>``) are ignored, so gravity acts on every link as the experiment contract requires.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .transforms import pose_transform

MOVABLE = ('revolute', 'continuous', 'prismatic')
SUPPORTED = MOVABLE + ('fixed',)


@dataclass
class Inertial:
    """URDF <inertial>: mass [kg]; origin (4x4) of the CoM frame in the link frame; inertia [kg m^2] about the
    CoM in that frame's axes (3x3, symmetric)."""
    mass_kg: float
    origin: np.ndarray
    inertia: np.ndarray


@dataclass
class Joint:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray                      # 4x4, child joint frame in the parent link frame
    axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    lower: float | None = None
    upper: float | None = None
    effort: float | None = None
    velocity: float | None = None
    damping: float = 0.0                   # viscous [N m s/rad]
    friction: float = 0.0                  # Coulomb [N m]

    @property
    def movable(self) -> bool:
        return self.type in MOVABLE


@dataclass
class UrdfRobot:
    name: str
    inertials: dict[str, Inertial | None]   # every link (None: no <inertial>)
    joints: dict[str, Joint]

    def child_joints(self, link: str) -> list[Joint]:
        return [j for j in self.joints.values() if j.parent == link]

    def parent_joint(self, link: str) -> Joint | None:
        for j in self.joints.values():
            if j.child == link:
                return j
        return None

    def chain(self, base_link: str, tip_link: str) -> list[Joint]:
        """Joints from base_link to tip_link, in order. Raises ValueError if tip_link is not below base_link."""
        for link in (base_link, tip_link):
            if link not in self.inertials:
                raise ValueError(f"URDF '{self.name}' has no link '{link}' (links: {sorted(self.inertials)})")
        out, link = [], tip_link
        while link != base_link:
            joint = self.parent_joint(link)
            if joint is None:
                raise ValueError(f"link '{tip_link}' is not below '{base_link}' in URDF '{self.name}'")
            out.append(joint)
            link = joint.parent
        return out[::-1]


def _floats(text: str | None, default, n: int) -> np.ndarray:
    if text is None:
        return np.asarray(default, dtype=float)
    values = np.array([float(v) for v in text.split()])
    if values.shape != (n,):
        raise ValueError(f"expected {n} numbers, got '{text}'")
    return values


def _origin(elem) -> np.ndarray:
    origin = elem.find('origin') if elem is not None else None
    if origin is None:
        return np.eye(4)
    return pose_transform(_floats(origin.get('xyz'), (0, 0, 0), 3), _floats(origin.get('rpy'), (0, 0, 0), 3))


def _opt_float(elem, key):
    if elem is None or elem.get(key) is None:
        return None
    return float(elem.get(key))


def parse_urdf(path: str | Path) -> UrdfRobot:
    """Parse a URDF file. Raises ValueError for unsupported joint types or malformed numbers."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise ValueError(f'cannot read URDF {path}: {exc}') from None
    inertials: dict[str, Inertial | None] = {}
    for link in root.findall('link'):
        inertial = link.find('inertial')
        if inertial is None:
            inertials[link.get('name')] = None
            continue
        mass = float(inertial.find('mass').get('value'))
        i = inertial.find('inertia')
        ixx, ixy, ixz, iyy, iyz, izz = (float(i.get(k, 0.0)) for k in ('ixx', 'ixy', 'ixz', 'iyy', 'iyz', 'izz'))
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        inertials[link.get('name')] = Inertial(mass, _origin(inertial), tensor)
    joints: dict[str, Joint] = {}
    for j in root.findall('joint'):
        name, jtype = j.get('name'), j.get('type')
        if jtype not in SUPPORTED:
            raise ValueError(f"URDF joint '{name}' has type '{jtype}'; supported: {', '.join(SUPPORTED)}")
        limit, dyn, axis = j.find('limit'), j.find('dynamics'), j.find('axis')
        ax = _floats(axis.get('xyz') if axis is not None else None, (1, 0, 0), 3)
        if jtype in MOVABLE:
            if np.linalg.norm(ax) == 0:
                raise ValueError(f"URDF joint '{name}' has a zero axis")
            ax = ax / np.linalg.norm(ax)
        lower, upper = _opt_float(limit, 'lower'), _opt_float(limit, 'upper')
        if jtype == 'continuous':
            lower = upper = None
        joints[name] = Joint(
            name=name, type=jtype, parent=j.find('parent').get('link'), child=j.find('child').get('link'),
            origin=_origin(j), axis=ax, lower=lower, upper=upper,
            effort=_opt_float(limit, 'effort'), velocity=_opt_float(limit, 'velocity'),
            damping=_opt_float(dyn, 'damping') or 0.0, friction=_opt_float(dyn, 'friction') or 0.0)
    return UrdfRobot(name=root.get('name', path.stem), inertials=inertials, joints=joints)
