"""The contract's flexible loop (CONTRACTS.md section 2, 'Loop geometry'), the seed paper's model made exact.

Rest shape: a regular N-gon in the x-z plane of the grasp frame G, top vertex at G's origin, centre at (0, 0, R).
Two branches of N/2 links leave G; link k of a branch starts at joint k, J_k = Ry(theta_k) Rz(phi_k):

    left:  L_1 = G Ry(-pi/N) J_1,       L_{k+1} = L_k T(l, 0, 0) Ry(-2 pi/N) J_{k+1}
    right: L_1 = G Ry(pi + pi/N) J_1,   L_{k+1} = L_k T(l, 0, 0) Ry(+2 pi/N) J_{k+1}

l = 2 R sin(pi/N). Each branch end E = L_{N/2} T(l, 0, 0) is welded (6 constraints) to C Ry(pi/N - pi) (left)
and C Ry(-pi/N) (right). Springs V = sum (k_theta theta^2 + k_phi phi^2) / 2; links are solid cylinders of mass
m/N along their x axis, centred at (l/2, 0, 0).
"""
from __future__ import annotations

import math

import numpy as np

from .model import ModelBuilder, Spring
from .rigid_body import roty, solid_cylinder_inertia, trans

K_THETA = 'k_theta'
K_PHI = 'k_phi'


def loop_coordinate_names(n_links: int) -> list[str]:
    """(theta_1, phi_1, ..., theta_{N/2}, phi_{N/2}) of the left branch, then the right branch."""
    names = []
    for side in ('left', 'right'):
        for k in range(1, n_links // 2 + 1):
            names += [f'loop_{side}_theta_{k}', f'loop_{side}_phi_{k}']
    return names


def add_contract_loop(builder: ModelBuilder, n_links: int, radius_m: float, mass_kg: float, tube_radius_m: float,
                      grasp_coord: int, grasp_offset: np.ndarray, clamp_pose: np.ndarray,
                      k_theta: float = 1.0, k_phi: float = 1.0) -> dict:
    """Add the loop below the grasp frame G = frame(grasp_coord) * grasp_offset; returns coordinate indices.

    clamp_pose: C in the base frame (4x4). k_theta, k_phi: spring coefficients [N m/rad] (named coefficients
    ``k_theta`` and ``k_phi`` of the model).
    """
    if n_links < 4 or n_links % 2:
        raise ValueError(f'the loop needs an even number of links >= 4, got {n_links}')
    N = n_links
    half = N // 2
    length = 2.0 * radius_m * math.sin(math.pi / N)
    link_mass = mass_kg / N
    inertia = solid_cylinder_inertia(link_mass, tube_radius_m, length, axis=0)
    com = np.array([0.5 * length, 0.0, 0.0])
    kt = builder.add_coefficient(K_THETA, k_theta, 'loop in-plane bending stiffness (spring on every theta joint)',
                                 'N m/rad')
    kp = builder.add_coefficient(K_PHI, k_phi, 'loop out-of-plane bending stiffness (spring on every phi joint)',
                                 'N m/rad')
    first = {'left': roty(-math.pi / N), 'right': roty(math.pi + math.pi / N)}
    step = {'left': roty(-2.0 * math.pi / N), 'right': roty(2.0 * math.pi / N)}
    target = {'left': clamp_pose @ roty(math.pi / N - math.pi), 'right': clamp_pose @ roty(-math.pi / N)}
    coords = {'left': [], 'right': [], 'theta': [], 'phi': []}
    for side in ('left', 'right'):
        parent = grasp_coord
        origin = grasp_offset @ first[side]
        for k in range(1, half + 1):
            th = builder.add_coordinate(f'loop_{side}_theta_{k}', parent, origin, [0.0, 1.0, 0.0])
            ph = builder.add_coordinate(f'loop_{side}_phi_{k}', th, np.eye(4), [0.0, 0.0, 1.0])
            builder.add_body(ph, link_mass, com, inertia)
            builder.add_term(Spring(th, kt))
            builder.add_term(Spring(ph, kp))
            coords[side] += [th, ph]
            coords['theta'].append(th)
            coords['phi'].append(ph)
            parent = ph
            origin = trans(length, 0.0, 0.0) @ step[side]
        builder.add_frame(f'loop_{side}_end', parent, trans(length, 0.0, 0.0))
        builder.add_weld(f'clamp_{side}', parent, trans(length, 0.0, 0.0), target[side])
    builder.description.update({'object': 'loop', 'loop_links': N, 'loop_link_length_m': length})
    return coords


def rest_shape_vertices(n_links: int, radius_m: float) -> np.ndarray:
    """Vertices j = 0..N-1 of the rest shape in the grasp frame G: (R sin(2 pi j/N), 0, R - R cos(2 pi j/N))."""
    j = np.arange(n_links)
    a = 2.0 * np.pi * j / n_links
    return np.stack([radius_m * np.sin(a), np.zeros(n_links), radius_m - radius_m * np.cos(a)], axis=1)
