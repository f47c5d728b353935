"""Rod description YAML (CONTRACTS.md section 4): what the planner, the simulator and the nodes know of a rod.

```yaml
length: 0.9          # [m] whole rod
radius: 0.002        # h [m]
L_gb: 0.034          # [m]; or loop_height: h_f [m] (L_gb = h_f / 0.9066); or youngs_modulus [Pa] with density [kg/m^3]
friction: 0.5        # optional Coulomb coefficient with the table
g: 9.81              # optional [m/s^2], used only with youngs_modulus/density
natural_curvature: 0 # optional [1/m]: curvature of the rod at rest, in the table's plane once laid (> 0 turns left)
```
"""
from dataclasses import dataclass
import math

import yaml

from .scaling import RodScales

_KNOWN = {'length', 'radius', 'L_gb', 'loop_height', 'youngs_modulus', 'density', 'friction', 'g', 'name',
          'natural_curvature'}
_SIGNED = {'natural_curvature'}
#: the contract's three ways to give the rod's stiffness; exactly one of them
_STIFFNESS_FORMS = ('L_gb', 'loop_height', 'youngs_modulus')
#: longest rod accepted [m]: the whole rod hangs from the gripper at the start; a longer one means the file's values
#: are not in metres (the contract's unit)
MAX_LENGTH_M = 20.0


class RodDescriptionError(ValueError):
    """A rod description that cannot be used (missing, non-physical or unknown fields)."""


@dataclass(frozen=True)
class RodDescription:
    """A rod in SI units with its deployment scales (L_gb and ks_bar with the contract's conventions)."""

    length_m: float
    radius_m: float
    gravito_bending_length_m: float
    friction: float = None            # Coulomb coefficient with the table, None if not given
    youngs_modulus_pa: float = None
    density_kg_m3: float = None
    name: str = ''
    natural_curvature_per_m: float = 0.0   # rest curvature, in the table's plane once laid (> 0 turns left)

    @property
    def scales(self):
        return RodScales(self.gravito_bending_length_m, self.radius_m)

    @property
    def ks_bar(self):
        return self.scales.ks_bar

    @property
    def length_bar(self):
        """Rod length in units of L_gb (the largest suspended length the planner may ask for)."""
        return self.length_m / self.gravito_bending_length_m

    @property
    def hanging_height_m(self):
        """Height of the held node when the rod hangs at rest with its free end just touching the table (CONTRACTS.md
        section 4's hanging pose): the centreline at z = h at the free end, plus the length, plus the stretch under
        its own weight rho g L^2 / (2 E) = L^2 / (4 L_gb ks_bar) (5.0 mm for the paper's rod #3)."""
        return self.radius_m + self.length_m + self.length_m ** 2 / (4.0 * self.gravito_bending_length_m * self.ks_bar)


def rod_description_from_dict(d, source='rod description'):
    """Validate a mapping (as read from YAML or ROS parameters) into a :class:`RodDescription`."""
    if not isinstance(d, dict):
        raise RodDescriptionError(f'{source}: expected a mapping with length, radius and L_gb (or loop_height, '
                                  f'or youngs_modulus with density)')
    unknown = sorted(set(d) - _KNOWN)
    if unknown:
        raise RodDescriptionError(f'{source}: unknown field(s) {", ".join(unknown)} '
                                  f'(known: {", ".join(sorted(_KNOWN))})')
    for key in ('length', 'radius'):
        if key not in d:
            raise RodDescriptionError(f'{source}: missing "{key}" [m]')
    values = {}
    for key in _KNOWN - {'name'}:
        if d.get(key) is None:
            continue
        try:
            if isinstance(d[key], bool):        # YAML's yes / no / true / false are no lengths or coefficients
                raise TypeError
            v = float(d[key])
        except (TypeError, ValueError):
            raise RodDescriptionError(f'{source}: "{key}" must be a number, got {d[key]!r}') from None
        if key in _SIGNED:
            if not math.isfinite(v):
                raise RodDescriptionError(f'{source}: "{key}" must be finite, got {d[key]!r}')
        elif not math.isfinite(v) or (v <= 0 and key != 'friction') or v < 0:
            raise RodDescriptionError(f'{source}: "{key}" must be {"non-negative" if key == "friction" else "positive"}'
                                      f' and finite, got {d[key]!r}')
        values[key] = v
    forms = [k for k in _STIFFNESS_FORMS if k in values]
    if len(forms) > 1:
        raise RodDescriptionError(f'{source}: gives both {forms[0]} and {forms[1]}; give exactly one of L_gb, '
                                  f'loop_height, or youngs_modulus with density')
    if 'youngs_modulus' in values and 'density' not in values:
        raise RodDescriptionError(f'{source}: youngs_modulus needs density [kg/m^3] (or give L_gb or loop_height)')
    if values['length'] > MAX_LENGTH_M:
        raise RodDescriptionError(f'{source}: length {values["length"]:g} m is longer than {MAX_LENGTH_M:g} m: '
                                  f'the rod file\'s values must be in metres')
    try:
        scales = RodScales.from_description(values['radius'], L_gb=values.get('L_gb'),
                                            loop_height=values.get('loop_height'),
                                            youngs_modulus=values.get('youngs_modulus'),
                                            density=values.get('density'), g=values.get('g', 9.81))
    except ValueError as e:
        raise RodDescriptionError(f'{source}: {e}') from None
    if values['radius'] >= scales.gravito_bending_length_m:
        raise RodDescriptionError(f'{source}: radius {values["radius"]:g} m is not smaller than L_gb '
                                  f'({scales.gravito_bending_length_m:.4g} m): no slender rod (the rod file\'s values '
                                  f'must be in metres)')
    if values['length'] <= 2.0 * scales.gravito_bending_length_m:
        raise RodDescriptionError(f'{source}: length {values["length"]} m is not longer than 2 L_gb '
                                  f'({2 * scales.gravito_bending_length_m:.4g} m): nothing left to deploy')
    return RodDescription(length_m=values['length'], radius_m=values['radius'],
                          gravito_bending_length_m=scales.gravito_bending_length_m,
                          friction=values.get('friction'), youngs_modulus_pa=values.get('youngs_modulus'),
                          density_kg_m3=values.get('density'), name=str(d.get('name', '')),
                          natural_curvature_per_m=values.get('natural_curvature', 0.0))


class _DuplicateKey(yaml.YAMLError):
    pass


class _UniqueKeyLoader(yaml.SafeLoader):
    """A safe loader that refuses a key given twice (PyYAML would keep the last one silently)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise _DuplicateKey(f'"{key}" is given twice (line {key_node.start_mark.line + 1})')
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def load_rod_description(path):
    """Read and validate a rod description YAML file."""
    try:
        with open(path) as f:
            d = yaml.load(f, Loader=_UniqueKeyLoader)
    except OSError as e:
        raise RodDescriptionError(f'cannot read rod description {path}: {e.strerror}') from None
    except _DuplicateKey as e:
        raise RodDescriptionError(f'{path}: {e}') from None
    except yaml.YAMLError as e:                       # one line: PyYAML's message spans several
        raise RodDescriptionError(f'rod description {path} is not valid YAML: {" ".join(str(e).split())}') from None
    return rod_description_from_dict(d, source=str(path))
