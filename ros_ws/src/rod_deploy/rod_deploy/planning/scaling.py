"""Scaling analysis of rod deployment (paper Sec. 3.2.4, Eq. 11 and Eq. 16).

Conventions (CONTRACTS.md section 4, the paper's Eq. 16 and the released code):

* gravito-bending length  L_gb = (E h^2 / (8 rho g))^(1/3) = (k_b / (2 pi h^2 rho g))^(1/3)   [m]
  with bending stiffness k_b = E pi h^4 / 4 and h the rod *radius*;
* normalised stretching stiffness  k_s_bar = k_s L_gb^2 / k_b = 4 L_gb^2 / h^2   (k_s = E pi h^2);
* normalised suspended length  ls_bar = l_s / L_gb, curvature  kappa_bar = kappa L_gb,
  gripper position  q_bar = (q_M - q_C) / L_gb.

In these units the weight per unit length is rho A g = k_b / (2 L_gb^3), so the dimensionless gravity number
``rho A g L_gb^3 / k_b`` equals :data:`GRAVITY_NUMBER` = 1/2.  Forces are made dimensionless with
k_b / L_gb^2 in this package (the paper's F_bar = F h^2 / k_b equals that times 4 / k_s_bar).

Loop height (paper Sec. 6.1).  The constant 0.9066 quoted in the paper (after Pan et al. 2020) is the height of a
folded heavy elastica (the "crepe" fold: a rod lying on a table and folded back over itself) measured in the
*natural* gravito-bending length ``(k_b / (rho A g))^(1/3) = 2^(1/3) L_gb``.  In the L_gb of Eq. 16 the same fold is
``0.9066 * 2^(1/3) = 1.1422`` L_gb high (see ``test_scaling.py`` and ``test_der_loop_height``).  The contract
converts a measured loop height with ``L_gb = h_f / 0.9066`` (:func:`gravito_bending_length_from_loop_height`);
:func:`gravito_bending_length_from_loop_height_consistent` gives the value consistent with Eq. 16.
"""
from dataclasses import dataclass
import math

#: standard gravity used by the paper's released code [m/s^2]
G_RELEASED_CODE = 10.0
#: rho A g L_gb^3 / k_b with the Eq. 16 convention of L_gb
GRAVITY_NUMBER = 0.5
#: h_f / L_gb as written in the paper and the contract (natural gravito-bending length, see module docstring)
LOOP_HEIGHT_COEFFICIENT = 0.9066
#: h_f / L_gb for the folded-loop height with the Eq. 16 convention, 0.9066 * 2^(1/3)
LOOP_HEIGHT_COEFFICIENT_EQ16 = LOOP_HEIGHT_COEFFICIENT * 2.0 ** (1.0 / 3.0)


def bending_stiffness(youngs_modulus_pa, radius_m):
    """k_b = E pi h^4 / 4 [N m^2] of a solid circular rod of radius h."""
    return youngs_modulus_pa * math.pi * radius_m ** 4 / 4.0


def stretching_stiffness(youngs_modulus_pa, radius_m):
    """k_s = E pi h^2 [N]."""
    return youngs_modulus_pa * math.pi * radius_m ** 2


def gravito_bending_length(youngs_modulus_pa, radius_m, density_kg_m3, g=9.81):
    """L_gb = (E h^2 / (8 rho g))^(1/3) [m] (paper Eq. 16, contract convention)."""
    _positive(youngs_modulus_pa=youngs_modulus_pa, radius_m=radius_m, density_kg_m3=density_kg_m3, g=g)
    return (youngs_modulus_pa * radius_m ** 2 / (8.0 * density_kg_m3 * g)) ** (1.0 / 3.0)


def gravito_bending_length_from_stiffness(bending_stiffness_nm2, radius_m, density_kg_m3, g=9.81):
    """L_gb = (k_b / (2 pi h^2 rho g))^(1/3) [m] (paper Eq. 11); equal to Eq. 16 for k_b = E pi h^4 / 4."""
    _positive(bending_stiffness_nm2=bending_stiffness_nm2, radius_m=radius_m, density_kg_m3=density_kg_m3, g=g)
    return (bending_stiffness_nm2 / (2.0 * math.pi * radius_m ** 2 * density_kg_m3 * g)) ** (1.0 / 3.0)


def gravito_bending_length_from_loop_height(loop_height_m):
    """L_gb = h_f / 0.9066 [m] as the contract and the paper (Sec. 6.1) state it."""
    _positive(loop_height_m=loop_height_m)
    return loop_height_m / LOOP_HEIGHT_COEFFICIENT


def gravito_bending_length_from_loop_height_consistent(loop_height_m):
    """L_gb (Eq. 16 convention) from a folded-loop height: h_f / 1.1422 [m] (see module docstring)."""
    _positive(loop_height_m=loop_height_m)
    return loop_height_m / LOOP_HEIGHT_COEFFICIENT_EQ16


def normalized_stretching_stiffness(gravito_bending_length_m, radius_m):
    """k_s_bar = 4 L_gb^2 / h^2 (Eq. 16)."""
    _positive(gravito_bending_length_m=gravito_bending_length_m, radius_m=radius_m)
    return 4.0 * gravito_bending_length_m ** 2 / radius_m ** 2


def normalized_suspended_length(suspended_length_m, gravito_bending_length_m):
    """ls_bar = l_s / L_gb (Eq. 11)."""
    return suspended_length_m / gravito_bending_length_m


def normalized_curvature(curvature_per_m, gravito_bending_length_m):
    """kappa_bar = kappa L_gb (Eq. 11); keeps the sign of kappa."""
    return curvature_per_m * gravito_bending_length_m


@dataclass(frozen=True)
class RodScales:
    """Material scales of one rod: the only two numbers the deployment controller needs (paper Sec. 6.1)."""

    gravito_bending_length_m: float
    radius_m: float

    @property
    def ks_bar(self):
        return normalized_stretching_stiffness(self.gravito_bending_length_m, self.radius_m)

    def nondimensional_inputs(self, suspended_length_m, curvature_per_m):
        """(ls_bar, ks_bar, kappa_bar): the network/solver inputs in the released code's order."""
        L = self.gravito_bending_length_m
        return (normalized_suspended_length(suspended_length_m, L), self.ks_bar,
                normalized_curvature(curvature_per_m, L))

    @classmethod
    def from_description(cls, radius, L_gb=None, loop_height=None, youngs_modulus=None, density=None,
                         g=9.81, **_ignored):
        """Build from a contract rod description (radius and one of L_gb, loop_height, E with rho)."""
        if L_gb is not None:
            _positive(L_gb=L_gb)
            return cls(float(L_gb), float(radius))
        if loop_height is not None:
            return cls(gravito_bending_length_from_loop_height(loop_height), float(radius))
        if youngs_modulus is not None and density is not None:
            return cls(gravito_bending_length(youngs_modulus, radius, density, g), float(radius))
        raise ValueError('rod description needs one of L_gb, loop_height, or youngs_modulus with density')


def _positive(**values):
    for name, value in values.items():
        if not (value > 0 and math.isfinite(value)):
            raise ValueError(f'{name} must be positive and finite, got {value!r}')
