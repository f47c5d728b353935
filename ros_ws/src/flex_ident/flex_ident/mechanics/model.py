"""The mechanical model: a tree of one-degree-of-freedom coordinates, rigid bodies, welds and model terms.

Everything the integrator needs is here, in one place, independent of where it came from (URDF arm, contract loop,
a test pendulum):

* coordinates q (rad or m), each a revolute or prismatic joint whose frame is ``parent frame * origin *
  Rot(axis, q)``; the vector order is the configuration order (arm joints first, then loop angles), the tree order
  is derived;
* one composite rigid body per coordinate (mass, centre of mass and inertia about it, in the coordinate's frame);
* named frames (end effector, branch ends) and welds (6 holonomic constraints each: frame == target pose);
* **named coefficients** and **model terms** that use them. A term (spring, viscous damping, Coulomb friction,
  constant generalized force, input gain) adds to the potential or to the generalized forces and knows its own
  derivatives with respect to its coefficient. Identification picks any subset of coefficients by name as its
  parameter vector; a new physical effect is a new term plus a new coefficient.

Sign conventions: L = T - V; generalized forces F add to the right-hand side of the Euler-Lagrange equations; gravity
is a constant acceleration vector in the base frame.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

REVOLUTE, PRISMATIC = 0, 1


@dataclass(frozen=True)
class Spring:
    """Torsional/linear spring V = coef * (q - rest - offset)^2 / 2 on one coordinate; ``offset`` is the coefficient
    ``rest_coef`` (an identifiable rest-angle offset) or 0 when ``rest_coef`` is -1."""
    coord: int
    coef: int
    rest: float = 0.0
    rest_coef: int = -1


@dataclass(frozen=True)
class ViscousDamping:
    """F = -coef * qdot on one coordinate."""
    coord: int
    coef: int


@dataclass(frozen=True)
class CoulombFriction:
    """F = -coef * tanh(qdot / velocity_scale) (smoothed Coulomb friction) on one coordinate."""
    coord: int
    coef: int
    velocity_scale: float = 0.01


@dataclass(frozen=True)
class ConstantForce:
    """F = +coef on one coordinate (e.g. minus a torque sensor bias)."""
    coord: int
    coef: int


@dataclass(frozen=True)
class Coefficient:
    name: str
    value: float
    description: str            # in words a robotics engineer understands, with units
    unit: str = ''


@dataclass
class Weld:
    """Six holonomic constraints: the frame (coord, offset) equals ``target`` (4x4, base frame)."""
    name: str
    coord: int
    offset: np.ndarray
    target: np.ndarray


@dataclass
class MechanicalModel:
    coord_names: list
    parent: np.ndarray          # (n,) int, -1 = base frame
    origin: np.ndarray          # (n, 4, 4) parent frame -> joint frame at q = 0
    axis: np.ndarray            # (n, 3) unit, joint frame
    jtype: np.ndarray           # (n,) REVOLUTE | PRISMATIC
    body_mass: np.ndarray       # (n,) kg
    body_com: np.ndarray        # (n, 3) m, coordinate frame
    body_inertia: np.ndarray    # (n, 3, 3) kg m^2 about the com, coordinate-frame axes
    gravity: np.ndarray         # (3,) m/s^2, base frame
    frames: dict                # name -> (coord, 4x4 offset)
    welds: list                 # of Weld
    input_coords: np.ndarray    # (nu,) coordinates driven by the inputs u (arm joint torques)
    input_gain_coef: np.ndarray  # (nu,) coefficient index of each input's gain, -1 = gain 1
    coefficients: list          # of Coefficient
    terms: list                 # of Spring | ViscousDamping | CoulombFriction | ConstantForce
    measured_coords: np.ndarray  # (na,) coordinates measured by the joint encoders (the arm)
    end_effector: str = 'ee'    # frame used by the paper's cost
    description: dict = field(default_factory=dict)
    _kernel: object = field(default=None, repr=False, compare=False)

    @property
    def n(self) -> int:
        return len(self.coord_names)

    @property
    def n_constraints(self) -> int:
        return 6 * len(self.welds)

    @property
    def coef_names(self) -> list:
        return [c.name for c in self.coefficients]

    def coef_values(self) -> np.ndarray:
        return np.array([c.value for c in self.coefficients], dtype=float)

    def coef_index(self, name: str) -> int:
        for i, c in enumerate(self.coefficients):
            if c.name == name:
                return i
        raise KeyError(name)

    def kernel(self):
        """The compiled-kernel view of this model (a numba-friendly namedtuple of arrays), cached."""
        if self._kernel is None:
            from .tree_kinematics import pack_model
            self._kernel = pack_model(self)
        return self._kernel

    def extended(self, coefficients=(), terms=()) -> 'MechanicalModel':
        """A copy with added named coefficients and model terms (how a new physical effect plugs in: e.g.
        ``Coefficient('c_loop', 0.01, 'loop joint viscous damping', 'N m s/rad')`` and a ViscousDamping term on
        every loop coordinate using its index). Terms refer to coefficients by index in the extended list."""
        import copy
        out = copy.copy(self)
        names = set(self.coef_names)
        for c in coefficients:
            if c.name in names:
                raise ValueError(f'coefficient {c.name} already exists')
        out.coefficients = list(self.coefficients) + list(coefficients)
        out.terms = list(self.terms) + list(terms)
        out._kernel = None
        return out

    def with_weld_targets(self, targets) -> 'MechanicalModel':
        """A copy whose welds have the given target poses (used for continuation in static equilibrium)."""
        import copy
        out = copy.copy(self)
        out.welds = [Weld(w.name, w.coord, w.offset, np.asarray(t, dtype=float)) for w, t in zip(self.welds, targets)]
        out._kernel = None
        return out


class ModelBuilder:
    """Incremental construction of a :class:`MechanicalModel`."""

    def __init__(self, gravity=(0.0, 0.0, -9.81)):
        self.names, self.parent, self.origin, self.axis, self.jtype = [], [], [], [], []
        self.mass, self.com, self.inertia = [], [], []
        self.gravity = np.asarray(gravity, dtype=float)
        self.frames, self.welds = {}, []
        self.inputs, self.input_gain = [], []
        self.coefficients, self.terms = [], []
        self.measured = []
        self.description = {}

    def add_coordinate(self, name: str, parent: int, origin, axis, jtype: int = REVOLUTE) -> int:
        if name in self.names:
            raise ValueError(f'coordinate {name} defined twice')
        axis = np.asarray(axis, dtype=float)
        self.names.append(name)
        self.parent.append(int(parent))
        self.origin.append(np.asarray(origin, dtype=float))
        self.axis.append(axis / np.linalg.norm(axis))
        self.jtype.append(int(jtype))
        self.mass.append(0.0)
        self.com.append(np.zeros(3))
        self.inertia.append(np.zeros((3, 3)))
        return len(self.names) - 1

    def set_parent(self, coord: int, parent: int, origin):
        self.parent[coord] = int(parent)
        self.origin[coord] = np.asarray(origin, dtype=float)

    def add_body(self, coord: int, mass_kg: float, com_m, inertia, offset=None):
        """Attach a rigid body to a coordinate's frame (offset: coordinate frame -> body frame)."""
        from .rigid_body import combine_inertias
        com = np.asarray(com_m, dtype=float)
        inertia = np.asarray(inertia, dtype=float)
        if offset is not None:
            R = offset[:3, :3]
            com = offset[:3, 3] + R @ com
            inertia = R @ inertia @ R.T
        m, c, i = combine_inertias([(self.mass[coord], self.com[coord], self.inertia[coord]),
                                    (float(mass_kg), com, inertia)])
        self.mass[coord], self.com[coord], self.inertia[coord] = m, c, i

    def add_frame(self, name: str, coord: int, offset):
        self.frames[name] = (int(coord), np.asarray(offset, dtype=float))

    def add_weld(self, name: str, coord: int, offset, target):
        self.welds.append(Weld(name, int(coord), np.asarray(offset, dtype=float), np.asarray(target, dtype=float)))

    def add_coefficient(self, name: str, value: float, description: str, unit: str = '') -> int:
        for i, c in enumerate(self.coefficients):
            if c.name == name:
                return i
        self.coefficients.append(Coefficient(name, float(value), description, unit))
        return len(self.coefficients) - 1

    def add_term(self, term):
        self.terms.append(term)

    def add_input(self, coord: int, gain_coef: int = -1):
        self.inputs.append(int(coord))
        self.input_gain.append(int(gain_coef))

    def build(self) -> MechanicalModel:
        n = len(self.names)
        return MechanicalModel(
            coord_names=list(self.names), parent=np.array(self.parent, dtype=np.int64),
            origin=np.array(self.origin).reshape(n, 4, 4), axis=np.array(self.axis).reshape(n, 3),
            jtype=np.array(self.jtype, dtype=np.int64), body_mass=np.array(self.mass, dtype=float),
            body_com=np.array(self.com).reshape(n, 3), body_inertia=np.array(self.inertia).reshape(n, 3, 3),
            gravity=self.gravity.copy(), frames=dict(self.frames), welds=list(self.welds),
            input_coords=np.array(self.inputs, dtype=np.int64),
            input_gain_coef=np.array(self.input_gain, dtype=np.int64),
            coefficients=list(self.coefficients), terms=list(self.terms),
            measured_coords=np.array(self.measured, dtype=np.int64), description=dict(self.description))
