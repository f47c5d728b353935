"""The experiment description (CONTRACTS.md section 2) as the simulator needs it.

Loop geometry (contract): a regular N-gon of radius R in the x-z plane of the grasp frame G, top vertex at G,
centre at (0, 0, R) in G; link length l = 2 R sin(pi/N); branch ends welded to the clamp frame C
(E_left = C Ry(pi/N - pi), E_right = C Ry(-pi/N)).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from .transforms import pose_transform, rot_y, transform

DEFAULT_GRAVITY_M_S2 = 9.81


@dataclass
class ArmSpec:
    urdf_path: Path
    base_link: str
    tip_link: str
    joints: list[str]


@dataclass
class LoopSpec:
    links: int                 # N (even)
    radius_m: float            # R of the rest shape
    mass_kg: float             # total; m/N per link
    tube_radius_m: float       # solid-cylinder radius of every link
    grasp: np.ndarray          # 4x4: G in the tip_link frame
    clamp: np.ndarray          # 4x4: C in the base frame

    @property
    def link_length_m(self) -> float:
        return 2.0 * self.radius_m * np.sin(np.pi / self.links)

    @property
    def link_mass_kg(self) -> float:
        return self.mass_kg / self.links

    def end_targets(self) -> tuple[np.ndarray, np.ndarray]:
        """Clamp targets (4x4, base frame) of the left and right branch end frames."""
        n = self.links
        return (self.clamp @ transform(rot_y(np.pi / n - np.pi)), self.clamp @ transform(rot_y(-np.pi / n)))

    def rest_grasp(self) -> np.ndarray:
        """The grasp pose G (base frame) for which the rest shape closes exactly: G = C T(0, 0, -2R)."""
        return self.clamp @ transform(xyz=(0.0, 0.0, -2.0 * self.radius_m))


@dataclass
class ExperimentSpec:
    arm: ArmSpec
    loop: LoopSpec | None
    gravity_m_s2: np.ndarray   # (3,) in the base frame
    source: Path | None = None


def _pose(node, what: str) -> np.ndarray:
    node = node or {}
    if not isinstance(node, dict):
        raise ValueError(f'{what} must be a mapping with xyz and rpy, got {node!r}')
    xyz = node.get('xyz', [0.0, 0.0, 0.0])
    rpy = node.get('rpy', [0.0, 0.0, 0.0])
    if len(xyz) != 3 or len(rpy) != 3:
        raise ValueError(f'{what}: xyz and rpy need 3 numbers each, got xyz={xyz} rpy={rpy}')
    return pose_transform([float(v) for v in xyz], [float(v) for v in rpy])


def _positive(node: dict, key: str, what: str) -> float:
    if key not in node:
        raise ValueError(f'{what}.{key} is missing')
    value = float(node[key])
    if not value > 0:
        raise ValueError(f'{what}.{key} must be positive, got {value}')
    return value


def load_experiment(source: dict | str | Path, base_dir: str | Path | None = None) -> ExperimentSpec:
    """Read an experiment YAML (path) or an already-parsed dict.

    Paths inside are relative to the YAML file (for a dict: to ``base_dir``, default the working directory).
    Raises ValueError with the offending key on malformed input.
    """
    path = None
    if isinstance(source, (str, Path)):
        path = Path(source)
        try:
            data = yaml.safe_load(path.read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise ValueError(f'cannot read experiment {path}: {exc}') from None
        base_dir = path.parent
    else:
        data = source
        base_dir = Path(base_dir) if base_dir is not None else Path.cwd()
    if not isinstance(data, dict) or 'arm' not in data:
        raise ValueError('experiment must be a mapping with an `arm` section')
    arm = data['arm']
    for key in ('urdf', 'base_link', 'tip_link', 'joints'):
        if key not in arm:
            raise ValueError(f'arm.{key} is missing')
    urdf = Path(arm['urdf'])
    arm_spec = ArmSpec(urdf_path=urdf if urdf.is_absolute() else (Path(base_dir) / urdf),
                       base_link=str(arm['base_link']), tip_link=str(arm['tip_link']),
                       joints=[str(j) for j in arm['joints']])
    if not arm_spec.joints:
        raise ValueError('arm.joints is empty')
    gravity = data.get('gravity', DEFAULT_GRAVITY_M_S2)
    if np.ndim(gravity) == 0:
        gravity_vec = np.array([0.0, 0.0, -float(gravity)])
    else:
        gravity_vec = np.asarray(gravity, dtype=float)
        if gravity_vec.shape != (3,):
            raise ValueError(f'gravity must be a number (magnitude along -z) or 3 numbers, got {gravity}')
    loop = None
    obj = data.get('object')
    if obj is not None:
        if obj.get('type', 'loop') != 'loop':
            raise ValueError(f"object.type '{obj.get('type')}' is not supported (only 'loop')")
        links = int(obj.get('links', 0))
        if links < 2 or links % 2:
            raise ValueError(f'object.links must be an even number >= 2, got {obj.get("links")}')
        loop = LoopSpec(links=links, radius_m=_positive(obj, 'radius', 'object'),
                        mass_kg=_positive(obj, 'mass', 'object'),
                        tube_radius_m=_positive(obj, 'tube_radius', 'object'),
                        grasp=_pose(obj.get('grasp'), 'object.grasp'),
                        clamp=_pose(obj.get('clamp'), 'object.clamp'))
    return ExperimentSpec(arm=arm_spec, loop=loop, gravity_m_s2=gravity_vec, source=path)
