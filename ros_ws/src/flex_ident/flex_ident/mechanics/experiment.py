"""Experiment description (CONTRACTS.md section 2): YAML -> validated dataclasses.

Validated once, here, with one clear message per problem (:class:`ExperimentError`, a ValueError). Paths inside
the YAML are relative to the YAML file. Keys the contract does not name are accepted and ignored, except inside
``identify.parameters`` where every entry must be a parameter the model knows (checked when the model is built).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from .rigid_body import pose_xyz_rpy

DEFAULT_GRAVITY_MPS2 = 9.81


class ExperimentError(ValueError):
    """An experiment YAML that is missing something or contradicts itself."""


@dataclass(frozen=True)
class Pose:
    """A pose given as URDF-style xyz [m] and rpy [rad] (R = Rz(yaw) Ry(pitch) Rx(roll))."""
    xyz: tuple = (0.0, 0.0, 0.0)
    rpy: tuple = (0.0, 0.0, 0.0)

    def matrix(self) -> np.ndarray:
        return pose_xyz_rpy(self.xyz, self.rpy)


@dataclass(frozen=True)
class ArmSpec:
    urdf_path: str
    base_link: str
    tip_link: str
    joints: tuple
    gravity_mps2: tuple = (0.0, 0.0, -DEFAULT_GRAVITY_MPS2)   # in the base_link frame


@dataclass(frozen=True)
class LoopSpec:
    """The contract's flexible loop (CONTRACTS.md, 'Loop geometry')."""
    links: int
    radius_m: float
    mass_kg: float
    tube_radius_m: float
    grasp: Pose                 # G relative to tip_link
    clamp: Pose                 # C in the base frame

    @property
    def link_length_m(self) -> float:
        return 2.0 * self.radius_m * math.sin(math.pi / self.links)


@dataclass(frozen=True)
class ParameterSpec:
    name: str
    initial: float
    min: float
    max: float


@dataclass(frozen=True)
class IdentifySpec:
    parameters: tuple = ()                  # of ParameterSpec, in YAML order
    window_s: tuple | None = None           # (start, end) seconds from the first /joint_states stamp
    cost: str = 'end_effector'              # 'end_effector' (the paper's) or 'joint_angles'
    max_iterations: int = 30


@dataclass(frozen=True)
class Experiment:
    path: str
    arm: ArmSpec
    object: LoopSpec | None
    identify: IdentifySpec = field(default_factory=IdentifySpec)


def _require(mapping, key, where):
    if not isinstance(mapping, dict) or key not in mapping or mapping[key] is None:
        raise ExperimentError(f'{where}: missing "{key}"')
    return mapping[key]


def _number(value, where, positive=False, nonneg=False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ExperimentError(f'{where}: expected a number, got {value!r}')
    value = float(value)
    if not math.isfinite(value):
        raise ExperimentError(f'{where}: {value} is not finite')
    if positive and value <= 0:
        raise ExperimentError(f'{where}: must be positive, got {value}')
    if nonneg and value < 0:
        raise ExperimentError(f'{where}: must not be negative, got {value}')
    return value


def _vector(value, n, where) -> tuple:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise ExperimentError(f'{where}: expected a list of {n} numbers, got {value!r}')
    return tuple(_number(v, where) for v in value)


def _pose(value, where, required) -> Pose:
    if value is None:
        if required:
            raise ExperimentError(f'{where}: missing (a mapping with xyz and rpy)')
        return Pose()
    if not isinstance(value, dict):
        raise ExperimentError(f'{where}: expected a mapping with xyz and rpy, got {value!r}')
    unknown = set(value) - {'xyz', 'rpy'}
    if unknown:
        raise ExperimentError(f'{where}: unknown key(s) {sorted(unknown)} (a pose has xyz and rpy)')
    return Pose(xyz=_vector(value.get('xyz', [0, 0, 0]), 3, where + '.xyz'),
                rpy=_vector(value.get('rpy', [0, 0, 0]), 3, where + '.rpy'))


def _gravity(value, where) -> tuple:
    if isinstance(value, (list, tuple)):
        return _vector(value, 3, where)
    g = _number(value, where, nonneg=True)
    return (0.0, 0.0, -g)


def load_experiment(path: str | Path) -> Experiment:
    """Read and validate an experiment YAML. Raises :class:`ExperimentError` naming the problem."""
    path = Path(path)
    if not path.is_file():
        raise ExperimentError(f'experiment file {path} does not exist')
    try:
        doc = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ExperimentError(f'experiment file {path} is not valid YAML: {exc}') from None
    if not isinstance(doc, dict):
        raise ExperimentError(f'experiment file {path}: expected a mapping at the top level')
    where = str(path)
    base_dir = path.resolve().parent

    arm = _require(doc, 'arm', where)
    urdf_rel = _require(arm, 'urdf', where + ': arm')
    if not isinstance(urdf_rel, str):
        raise ExperimentError(f'{where}: arm.urdf must be a path, got {urdf_rel!r}')
    urdf_path = (base_dir / urdf_rel).resolve()
    if not urdf_path.is_file():
        raise ExperimentError(f'{where}: arm.urdf {urdf_rel} does not exist (looked for {urdf_path})')
    joints = _require(arm, 'joints', where + ': arm')
    if not isinstance(joints, list) or not joints or not all(isinstance(j, str) for j in joints):
        raise ExperimentError(f'{where}: arm.joints must be a non-empty list of joint names')
    dup = sorted({j for j in joints if joints.count(j) > 1})
    if dup:
        raise ExperimentError(f'{where}: arm.joints lists {dup} more than once')
    gravity = (0.0, 0.0, -DEFAULT_GRAVITY_MPS2)
    if 'gravity' in arm:
        gravity = _gravity(arm['gravity'], where + ': arm.gravity')
    elif 'gravity' in doc:
        gravity = _gravity(doc['gravity'], where + ': gravity')
    arm_spec = ArmSpec(urdf_path=str(urdf_path),
                       base_link=str(_require(arm, 'base_link', where + ': arm')),
                       tip_link=str(_require(arm, 'tip_link', where + ': arm')),
                       joints=tuple(joints), gravity_mps2=gravity)

    loop = None
    obj = doc.get('object')
    if obj is not None:
        ow = where + ': object'
        if not isinstance(obj, dict):
            raise ExperimentError(f'{ow}: expected a mapping')
        otype = obj.get('type', 'loop')
        if otype != 'loop':
            raise ExperimentError(f'{ow}.type is "{otype}"; the supported object type is "loop"')
        n = _require(obj, 'links', ow)
        if isinstance(n, bool) or not isinstance(n, int) or n < 4 or n % 2:
            raise ExperimentError(f'{ow}.links must be an even integer >= 4 (two branches of N/2 links), got {n!r}')
        radius = _number(_require(obj, 'radius', ow), ow + '.radius', positive=True)
        loop = LoopSpec(links=n, radius_m=radius,
                        mass_kg=_number(_require(obj, 'mass', ow), ow + '.mass', positive=True),
                        tube_radius_m=_number(_require(obj, 'tube_radius', ow), ow + '.tube_radius', nonneg=True),
                        grasp=_pose(obj.get('grasp'), ow + '.grasp', required=False),
                        clamp=_pose(obj.get('clamp'), ow + '.clamp', required=True))
        if loop.tube_radius_m >= radius:
            raise ExperimentError(f'{ow}.tube_radius {loop.tube_radius_m} must be smaller than radius {radius}')

    ident = doc.get('identify') or {}
    iw = where + ': identify'
    if not isinstance(ident, dict):
        raise ExperimentError(f'{iw}: expected a mapping')
    params = ident.get('parameters') or {}
    if not isinstance(params, dict):
        raise ExperimentError(f'{iw}.parameters: expected a mapping name -> {{initial, min, max}}')
    specs = []
    for name, spec in params.items():
        pw = f'{iw}.parameters.{name}'
        if not isinstance(spec, dict):
            raise ExperimentError(f'{pw}: expected a mapping with initial, min, max')
        initial = _number(_require(spec, 'initial', pw), pw + '.initial')
        lo = _number(spec['min'], pw + '.min') if spec.get('min') is not None else -math.inf
        hi = _number(spec['max'], pw + '.max') if spec.get('max') is not None else math.inf
        if not lo < hi:
            raise ExperimentError(f'{pw}: min {lo} is not below max {hi}')
        if not lo <= initial <= hi:
            raise ExperimentError(f'{pw}: initial value {initial} is outside its bounds [{lo}, {hi}]')
        specs.append(ParameterSpec(str(name), initial, lo, hi))
    window = ident.get('window')
    if window is not None:
        window = _vector(window, 2, iw + '.window')
        if not 0 <= window[0] < window[1]:
            raise ExperimentError(f'{iw}.window {list(window)} must be [start, end] with 0 <= start < end seconds')
    cost = ident.get('cost', 'end_effector')
    if cost not in ('end_effector', 'joint_angles'):
        raise ExperimentError(f'{iw}.cost is "{cost}"; use "end_effector" (the paper\'s) or "joint_angles"')
    max_it = ident.get('max_iterations', 30)
    if isinstance(max_it, bool) or not isinstance(max_it, int) or max_it < 1:
        raise ExperimentError(f'{iw}.max_iterations must be a positive integer, got {max_it!r}')
    return Experiment(path=str(path.resolve()), arm=arm_spec, object=loop,
                      identify=IdentifySpec(parameters=tuple(specs), window_s=window, cost=cost,
                                            max_iterations=max_it))
