"""An independent second opinion on the deployments: replay gripper trajectories in PyElastica 1.0.0 (a Cosserat
rod simulator, used as a library) and score the deployed shape with our Eq. 17.

    make bench-env          # .venv-bench with pyelastica==1.0.0, numpy, scipy, pyyaml, matplotlib
    PYTHONPATH=ros_ws/src/rod_deploy .venv-bench/bin/python benchmarks/pyelastica_replay.py --validate
    PYTHONPATH=ros_ws/src/rod_deploy .venv-bench/bin/python benchmarks/pyelastica_replay.py \
        [--rods 3] [--friction medium] [--methods nn,intuitive,published] [--patterns all] [--commit-results]

Set-up, the same as our simulator's (``rod_deploy.deployment.simulate``, CONTRACTS.md section 4) but in another
model of the rod: a Cosserat rod (shear and stretch, explicit position-Verlet steps) of the rod's E, density and
radius (nu = 0.5), gravity, PyElastica's rod-plane contact (penalty spring and damper on the elements plus the
plane's response force, on the elements touching it: centreline at most 1 um above the contact height, not
PyElastica's 0.1 mm band, on which the table held and braked the rod before it touched down, see
``simulator_gap_r9.md``) with Coulomb friction on the nodes' centreline velocity as a stick / slip projection over the
step (``NodalCoulombStickPlane``, the default since issue #10's third look: a sticking node is held still at any load
up to mu N, N the normal force the plane applies to the node since the study of the two simulators' disagreement,
``sims_disagreement.md``, with 5 mm elements instead of 1 cm; ``--friction-law centreline``:
``CentrelineCoulombPlane``, PyElastica's static / kinetic switch at the slip tolerance on the elements, under which a
laid rod loaded below mu N creeps (the published circle's free end 0.1 mm/s after the release); ``--friction-law pyelastica``: PyElastica's own
``RodPlaneContactWithAnisotropicFriction``, the same mu forward, backward and sideways, sideways on the rolling slip:
a laid rod rolls sideways under any sideways load, see ``friction_canonical.py``), uniform viscous damping (the same
2/s as ours). The rod starts straight up from the free end (on the table at the pattern's first point)
to the trajectory's first (hanging) pose, uniformly stretched to reach it, and settles there at rest with both ends
held; then the last node follows the gripper's position and the last element its directors (d1 = x_gripper,
d3 = -z_gripper), the free end held during the lead-in (the same ``replay_schedule`` as our simulator, 0.01 m/s);
then the gripper stays still for ``--settle`` s. The deployed shape: the nodes in contact with the table (centreline
within 0.3 mm of z = h: the laid rod on PyElastica's element contact ripples by about 0.1 mm, and the rod rises
0.7 mm within the next 1 cm element where it lifts off), from the free end to where the rod lifts off; the final
nodes are kept in the .json.

``--validate`` checks the set-up against closed forms first: a rod hanging from its top stretches by
rho g L^2 / (2 E), and a short horizontal cantilever under its own weight deflects by q L^4 / (8 EI) at its tip.

Patterns, rods and planners are those of ``deployment_table.py`` (``published``: the released planner's trajectories,
rod #3). Results: ``pyelastica_replay.md`` / ``.json`` beside our simulator's table, the two e_mean side by side when
``deployment_table.md`` of the same results folder has the case.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402

try:
    import elastica as ea
except ImportError:                     # pragma: no cover - the benchmark environment is separate
    sys.exit('pyelastica_replay: error: PyElastica is not installed here; run `make bench-env` and use '
             '.venv-bench/bin/python')

from elastica._contact_functions import _calculate_contact_forces_rod_plane  # noqa: E402
from elastica._linalg import _batch_norm, _batch_product_i_ik_to_k, _batch_product_i_k_to_ik  # noqa: E402
from elastica.contact_utils import (_elements_to_nodes_inplace, _find_slipping_elements,  # noqa: E402
                                    _node_to_element_mass_or_force, _node_to_element_velocity)
from numba import njit  # noqa: E402
from rod_deploy.deployment.metrics import eq17_error  # noqa: E402
from rod_deploy.deployment.simulate import (FRICTION_LEVELS, LAID_HEIGHT_TOLERANCE_M, deployed_shape,  # noqa: E402
                                            material_parameters, replay_schedule)
from rod_deploy.planning.rod_description import rod_description_from_dict  # noqa: E402

G = 9.81
FLIP = np.diag([1.0, -1.0, -1.0])      # director rows (d1, d2, d3) = FLIP @ R_gripper^T: d1 = x_g, d3 = -z_g


@dataclass
class ElasticaSettings:
    #: PyElastica element length; 1 cm until the study of the two simulators' disagreement (`sims_disagreement.md`):
    #: unconverged there (nn's letter U 0.256 cm at 1 cm, 0.106 at 5 mm; our DER 0.081, converged)
    element_length_m: float = 0.005
    #: position-Verlet step (explicit: below the axial wave's crossing time dl / c, 1.8e-4 s for 5 mm elements of
    #: rod #3, 1.6e-4 s for rod #2; ``replay_in_elastica`` refuses a step above it)
    dt_s: float = 1.5e-4
    rotary_inertia_scale: float = 100.0   # the elements' rotary inertia times this (see rotary_inertia_scaled)
    damping_per_s: float = 2.0        # uniform viscous damping, as in our simulator
    contact_k_n_m: float = 200.0      # penalty stiffness of the table per element [N/m]
    contact_nu_n_s_m: float = 0.1     # contact damping per element [N s/m]
    #: an element counts as touching the table while its centreline is at most this above the contact height: it
    #: gets PyElastica's plane response (and with it the stick law's normal force, hence friction). PyElastica's
    #: own value, 1e-4 m (until `simulator_gap_r9.md`), let the table hold and brake elements 0.1 mm above it:
    #: the laid rod floated on that band, and the rod still descending to its touch-down point was gripped by
    #: friction up to an element early (rod #3's circle at mu 1: 0.234 cm; 0.065 at 1e-6)
    contact_surface_tol_m: float = 1e-6
    slip_velocity_tol_m_s: float = 1e-4   # below this an element is sticking (PyElastica's static friction)
    hang_settle_s: float = 2.0        # hanging at rest before the replay
    settle_s: float = 1.0             # gripper still at the end
    gripper_speed_m_s: float = 0.01   # the replay's speed cap (our simulator's ``max_gripper_speed_m_s``)
    #: a node lies on the table if z <= h + this (our simulator's readout, ``deployed_shape``; the laid rod ripples by
    #: +-0.1 mm here)
    contact_tolerance_m: float = LAID_HEIGHT_TOLERANCE_M
    grid_s: float = 0.005             # the gripper's pose precomputed on this grid, linear in between
    friction_law: str = 'stick'       # NodalCoulombStickPlane; 'centreline' (CentrelineCoulombPlane: creeps),
    #                                   'pyelastica' (RodPlaneContactWithAnisotropicFriction: creeps and rolls)
    #: the stick law's normal force N: True, the normal force the plane applies to the node (PyElastica's plane
    #: response, penalty spring and damper, as distributed to the nodes); False (until the study of the two simulators'
    #: disagreement): the plane response alone, on the elements within 0.1 mm of the plane, half to each node, which
    #: at the lift-off point, where the suspended rod presses on the table, gave friction 20-65 % of our DER's normal
    #: force (nn's letter U, `sims_disagreement.md`)
    applied_normal: bool = True


def rotary_inertia_scaled(rod_e, scale):
    """Scale the elements' rotary inertia (rho I, rho J) by ``scale``. Explicit steps of a Cosserat rod are bounded
    by the shear-rotation mode, omega = sqrt(G A / (rho I)) = 2 sqrt(G / rho) / h (16,000 rad/s for rod #3, dt <
    1.25e-4 s, whatever the element length); rotary inertia is negligible in a quasi-static deployment (rho I omega^2
    against the weight), and scaling it by 100 leaves the axial wave's dl / c (1.8e-4 s for 5 mm elements of rod #3)
    as the bound. Statics are unchanged."""
    rod_e.mass_second_moment_of_inertia *= scale
    rod_e.inv_mass_second_moment_of_inertia /= scale


def rod_material(rod):
    """(E [Pa], rho [kg/m^3]) as our simulator derives them from the rod description."""
    p = material_parameters(rod, 0.5, 0.0)
    A = math.pi * rod.radius_m ** 2
    return p.EA / A, p.rho_A / A


@njit(cache=True)
def _centreline_coulomb(origin, normal, surface_tol, slip_tol, k, nu, mu, radius, mass, position, velocity,
                        internal_forces, external_forces):
    """PyElastica's rod-plane contact (its normal force, its static / kinetic switch at the slip tolerance) with
    isotropic Coulomb friction on the elements' centreline velocity and no friction torque: the friction law of
    its axial direction, applied in every in-plane direction."""
    n_mag, no_contact = _calculate_contact_forces_rod_plane(origin, normal, surface_tol, k, nu, radius, mass,
                                                            position, velocity, internal_forces, external_forces)
    v = _node_to_element_velocity(mass, velocity)
    v_t = v - _batch_product_i_k_to_ik(normal, _batch_product_i_ik_to_k(normal, v))
    slip = _find_slipping_elements(v_t, slip_tol)        # 1: sticking, 0: slipping (linear in between)
    speed = _batch_norm(v_t)
    kinetic = v_t * (-(1.0 - slip) * mu * n_mag / (speed + 1e-14))
    for j in no_contact:
        kinetic[:, j] = 0.0
    _elements_to_nodes_inplace(kinetic, external_forces)
    f = _node_to_element_mass_or_force(internal_forces + external_forces)
    f_t = f - _batch_product_i_k_to_ik(normal, _batch_product_i_ik_to_k(normal, f))
    f_mag = _batch_norm(f_t)
    static = f_t * (-np.minimum(f_mag, slip * mu * n_mag) / (f_mag + 1e-14))
    for j in no_contact:
        static[:, j] = 0.0
    _elements_to_nodes_inplace(static, external_forces)


class CentrelineCoulombPlane(ea.NoContact):
    """Rod-plane contact with Coulomb friction on the centreline (no rolling): ``--friction-law centreline``.

    PyElastica's own law (``RodPlaneContactWithAnisotropicFriction``) applies sideways friction to the contact
    point's slip, v + omega x r, with the no-slip force of a free solid cylinder, (r F - 2 T) / (3 r): the laid rod
    rolls sideways under any sideways load (a rigid round cylinder does). A laid rod rolls little in fact: rolling
    one stretch of length l relative to the rest twists the rod, and against bending the twist's compliance is
    (r / l)^2 EI / GJ, 0.2 % for r = 2 mm and l = 5 cm. In that model a straight rod under half the friction limit
    sideways rolls like a free cylinder, and an arc laid at rest keeps rolling (``friction_canonical.py``).
    Our DER's friction acts on the centreline too (no rolling), as in the paper's simulator."""

    def __init__(self, k, nu, mu, slip_velocity_tol, surface_tol=ElasticaSettings.contact_surface_tol_m):
        super().__init__()
        self.k, self.nu, self.mu = np.float64(k), np.float64(nu), np.float64(mu)
        self.slip_velocity_tol = np.float64(slip_velocity_tol)
        self.surface_tol = np.float64(surface_tol)

    @property
    def _allowed_system_two(self):
        return [ea.Plane]

    def apply_contact(self, system_one, system_two, time=np.float64(0.0)):
        _centreline_coulomb(system_two.origin, system_two.normal, self.surface_tol, self.slip_velocity_tol, self.k,
                            self.nu, self.mu, system_one.radius, system_one.mass, system_one.position_collection,
                            system_one.velocity_collection, system_one.internal_forces, system_one.external_forces)


@njit(cache=True)
def _nodal_coulomb_stick(origin, normal, surface_tol, k, nu, mu, dt, applied_normal, radius, mass, position,
                         velocity, internal_forces, external_forces):
    """PyElastica's rod-plane normal force, then Coulomb friction on the nodes' centreline velocity as a stick /
    slip projection over the step: a node in contact (normal force N: with ``applied_normal`` the normal force the
    plane applies to the node, else half of each adjacent element's plane response) gets the
    tangential force that stops it within this step, -(F_t + m v_t / dt), when that is within mu N (sticking, the
    node then stays exactly still), else mu N against its trial velocity v_t + dt F_t / m (slipping). The
    position-Verlet velocity update v += dt (F + f) / m then gives v_t = 0 on a sticking node."""
    n_before = normal[0] * external_forces[0] + normal[1] * external_forces[1] + normal[2] * external_forces[2]
    n_mag, no_contact = _calculate_contact_forces_rod_plane(origin, normal, surface_tol, k, nu, radius, mass,
                                                            position, velocity, internal_forces, external_forces)
    n_el = n_mag.shape[0]
    n_node = np.zeros(n_el + 1)
    if applied_normal:
        # the normal force the plane applies to each node (response, penalty spring and damper as distributed)
        n_after = normal[0] * external_forces[0] + normal[1] * external_forces[1] + normal[2] * external_forces[2]
        for i in range(n_el + 1):
            n_node[i] = max(n_after[i] - n_before[i], 0.0)
    else:
        in_contact = np.ones(n_el)
        for j in no_contact:
            in_contact[j] = 0.0
        for j in range(n_el):
            n_node[j] += 0.5 * in_contact[j] * n_mag[j]
            n_node[j + 1] += 0.5 * in_contact[j] * n_mag[j]
    for i in range(n_el + 1):
        if n_node[i] <= 0.0:
            continue
        f = internal_forces[:, i] + external_forces[:, i]
        fn = f[0] * normal[0] + f[1] * normal[1] + f[2] * normal[2]
        v = velocity[:, i]
        vn = v[0] * normal[0] + v[1] * normal[1] + v[2] * normal[2]
        stick = -(f - fn * normal) - mass[i] * (v - vn * normal) / dt
        s_mag = math.sqrt(stick[0] ** 2 + stick[1] ** 2 + stick[2] ** 2)
        limit = mu * n_node[i]
        if s_mag > limit:
            stick *= limit / s_mag            # slipping: mu N against the trial velocity (= -stick direction)
        external_forces[:, i] += stick


class NodalCoulombStickPlane(ea.NoContact):
    """Rod-plane contact with Coulomb friction on the nodes' centreline velocity, stick / slip over the step
    (``--friction-law stick``; see ``_nodal_coulomb_stick``).

    Why: PyElastica's static friction (in its own law and in ``CentrelineCoulombPlane``) cancels the element's
    current tangential force up to mu N while the element moves slower than the slip tolerance, but not its velocity,
    and its kinetic friction changes a slipping element's velocity by mu g dt = 1.5e-3 m/s per step (dt 3e-4 s), 15x
    the tolerance, so an element braked by it overshoots the sticking band instead of landing in it. A laid rod under
    a sustained load below mu N creeps: the published circle's free end moves 0.1 mm/s for 50 s after the gripper
    has left it (``replay_probe.py``); the canonical arc creeps as much at slip tolerance 1e-5 as at 1e-4 m/s (3.2 mm
    from 3 to 10 s) and 0.4x as much with half the step and half the element (``friction_canonical.md``; the two
    were changed together): not the tolerance but, as far as measured, the step's friction impulse sets it.
    Coulomb's law has no creep: the stick force here holds the node exactly, at any load up to mu N."""

    def __init__(self, k, nu, mu, dt, applied_normal=False, surface_tol=ElasticaSettings.contact_surface_tol_m):
        super().__init__()
        self.k, self.nu, self.mu, self.dt = np.float64(k), np.float64(nu), np.float64(mu), np.float64(dt)
        self.applied_normal = bool(applied_normal)
        self.surface_tol = np.float64(surface_tol)

    @property
    def _allowed_system_two(self):
        return [ea.Plane]

    def apply_contact(self, system_one, system_two, time=np.float64(0.0)):
        _nodal_coulomb_stick(system_two.origin, system_two.normal, self.surface_tol, self.k, self.nu, self.mu,
                             self.dt, self.applied_normal, system_one.radius, system_one.mass,
                             system_one.position_collection,
                             system_one.velocity_collection, system_one.internal_forces,
                             system_one.external_forces)


class _Simulator(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping, ea.Contact, ea.CallBacks):
    pass


class PrescribedEnds(ea.ConstraintBase):
    """The last node and last element follow the gripper (position, velocity, directors, omega = 0); node 0 is
    held at ``start`` until ``t_release``."""

    def __init__(self, grid_t, grid_p, grid_Q, start, t_release, **kwargs):
        super().__init__(**kwargs)
        self.grid_t, self.grid_p, self.grid_Q = grid_t, grid_p, grid_Q
        self.start = np.asarray(start, float)
        self.t_release = t_release
        self.dt_grid = grid_t[1] - grid_t[0]
        self.grid_v = np.vstack([np.diff(grid_p, axis=0) / self.dt_grid, np.zeros((1, 3))])
        self._cache_t, self._cache = None, None

    def _pose(self, time):
        """(p, Q, v) at ``time``, linear between grid poses (0.005 s apart: the blend of two directors that differ
        by at most 1e-3 rad is orthonormal to 1e-7), cached: values and rates are asked at the same times."""
        if time == self._cache_t:
            return self._cache
        u = min(max(float(time), 0.0), self.grid_t[-1]) / self.dt_grid
        k = min(int(u), len(self.grid_t) - 2)
        w = u - k
        self._cache_t = time
        self._cache = ((1 - w) * self.grid_p[k] + w * self.grid_p[k + 1],
                       (1 - w) * self.grid_Q[k] + w * self.grid_Q[k + 1], self.grid_v[k])
        return self._cache

    def constrain_values(self, system, time):
        p, Q, _ = self._pose(time)
        system.position_collection[:, -1] = p
        system.director_collection[:, :, -1] = Q
        if time <= self.t_release:
            system.position_collection[:, 0] = self.start

    def constrain_rates(self, system, time):
        _, _, v = self._pose(time)
        system.velocity_collection[:, -1] = v
        system.omega_collection[:, -1] = 0.0
        if time <= self.t_release:
            system.velocity_collection[:, 0] = 0.0


def replay_in_elastica(cases, rod, friction, settings=None, progress=True, snapshot_every_s=None):
    """Replay trajectories in PyElastica, one rod per case (t, position, quaternion, start_xy or None), all in one
    simulator (PyElastica steps its rods as one memory block: a batch costs far less than the cases one by one; the
    rods do not touch each other). A case whose trajectory ends earlier keeps its gripper still until the last one
    ends. Returns one dict(deployed_xy, nodes, gripper_path, replay_s) per case, and the wall time.
    ``snapshot_every_s``: also keep every rod's nodes every that many simulated seconds (``snapshots``: list of
    (time, (n, 3) nodes); a diagnostic)."""
    from scipy.spatial.transform import Rotation, Slerp
    s = settings or ElasticaSettings()
    wall = time.perf_counter()
    scheds = [replay_schedule(t, p, q, rod, start, s.gripper_speed_m_s) for t, p, q, start in cases]
    L, h = rod.length_m, rod.radius_m
    E, rho = rod_material(rod)
    n_el = max(int(round(L / s.element_length_m)), 4)
    dt_bound = (L / n_el) / math.sqrt(E / rho)               # the axial wave's crossing time of one element
    if s.dt_s >= dt_bound:
        raise ValueError(f'PyElastica step {s.dt_s:g} s is not below the axial wave\'s crossing time of one element, '
                         f'{dt_bound:.3g} s ({1e3 * L / n_el:.2f} mm elements): explicit steps would diverge; '
                         f'give a smaller --dt')
    t_total = s.hang_settle_s + max(sc.t[-1] for sc in scheds) + s.settle_s
    grid_t = np.arange(0.0, t_total + 2 * s.grid_s, s.grid_s)
    sim = _Simulator()
    plane = ea.Plane(plane_origin=np.zeros(3), plane_normal=np.array([0.0, 0.0, 1.0]))
    sim.append(plane)
    mu = np.array([friction, friction, friction])
    rods, grids = [], []
    for sched in scheds:
        # the gripper on a fine grid (hanging phase first: the pose of t = 0 held for hang_settle_s)
        tr = np.clip(grid_t - s.hang_settle_s, 0.0, sched.t[-1])
        grid_p = np.column_stack([np.interp(tr, sched.t, sched.position[:, k]) for k in range(3)])
        R = Slerp(sched.t, Rotation.from_quat(sched.quaternion))(tr).as_matrix()
        grid_Q = np.einsum('ij,nkj->nik', FLIP, R)          # FLIP @ R^T per row of the grid
        start = np.array([sched.start_xy[0], sched.start_xy[1], h])
        p0 = grid_p[0]
        normal = grid_Q[0][0].copy()
        normal[2] = 0.0
        normal /= np.linalg.norm(normal)
        rod_e = ea.CosseratRod.straight_rod(n_el, start, np.array([0.0, 0.0, 1.0]), normal, L, h, rho,
                                            youngs_modulus=E, shear_modulus=E / 3.0)
        rotary_inertia_scaled(rod_e, s.rotary_inertia_scale)
        # stretched uniformly from the free end to the first pose (the settling below finds the hanging shape)
        lam = np.linspace(0.0, 1.0, n_el + 1)
        rod_e.position_collection[:] = start[:, None] + lam[None] * (p0 - start)[:, None]
        sim.append(rod_e)
        sim.constrain(rod_e).using(PrescribedEnds, grid_t=grid_t, grid_p=grid_p, grid_Q=grid_Q, start=start,
                                   t_release=s.hang_settle_s + sched.t_release)
        sim.add_forcing_to(rod_e).using(ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -G]))
        if s.friction_law == 'centreline':
            sim.detect_contact_between(rod_e, plane).using(
                CentrelineCoulombPlane, k=s.contact_k_n_m, nu=s.contact_nu_n_s_m, mu=friction,
                slip_velocity_tol=s.slip_velocity_tol_m_s, surface_tol=s.contact_surface_tol_m)
        elif s.friction_law == 'stick':
            sim.detect_contact_between(rod_e, plane).using(
                NodalCoulombStickPlane, k=s.contact_k_n_m, nu=s.contact_nu_n_s_m, mu=friction, dt=s.dt_s,
                applied_normal=s.applied_normal, surface_tol=s.contact_surface_tol_m)
        else:
            sim.detect_contact_between(rod_e, plane).using(
                ea.RodPlaneContactWithAnisotropicFriction, k=s.contact_k_n_m, nu=s.contact_nu_n_s_m,
                slip_velocity_tol=s.slip_velocity_tol_m_s, static_mu_array=mu, kinetic_mu_array=mu)
        sim.dampen(rod_e).using(ea.AnalyticalLinearDamper, uniform_damping_constant=s.damping_per_s,
                                time_step=s.dt_s)
        rods.append(rod_e)
        grids.append(grid_p)
    sim.finalize()
    stepper = ea.PositionVerlet()
    steps = int(math.ceil(t_total / s.dt_s))
    now = np.float64(0.0)
    report = max(steps // 50, 1)
    snap_every = int(round(snapshot_every_s / s.dt_s)) if snapshot_every_s else 0
    snaps = [[] for _ in rods]
    for k in range(steps):
        now = stepper.step(sim, now, s.dt_s)
        if snap_every and (k + 1) % snap_every == 0:
            for i, rod_e in enumerate(rods):
                snaps[i].append((float(now), rod_e.position_collection.T.copy()))
        if progress and (k + 1) % report == 0:
            print(f'\r  pyelastica {len(cases)} rods, {100 * (k + 1) / steps:3.0f}% of {t_total:.0f} s simulated '
                  f'({time.perf_counter() - wall:.0f} s)', end='', file=sys.stderr, flush=True)
    if progress:
        print(file=sys.stderr)
    out = []
    for rod_e, grid_p, sched, snap in zip(rods, grids, scheds, snaps):
        nodes = rod_e.position_collection.T.copy()
        if not np.all(np.isfinite(nodes)):
            raise ValueError('PyElastica diverged (reduce --dt)')
        out.append({'deployed_xy': deployed_shape(nodes, h, s.contact_tolerance_m), 'nodes': nodes,
                    'gripper_path': grid_p,
                    'replay_s': float(sched.t[-1]), 'snapshots': snap,
                    't_release_s': s.hang_settle_s + sched.t_release})
    return out, time.perf_counter() - wall


# ---------------------------------------------------------------------------------------------- closed forms

def table_force_on_level_rod(gap_m, mu=0.5, settings=None):
    """The table's force on a short level rod (2 cm, 4 elements, rod #3's section and material) whose centreline is
    ``gap_m`` above the contact height, at rest but for a sideways velocity of 1 mm/s, loaded by its weight: the
    replay's contact law applied once. Returns (normal force, friction force) [N], summed over the nodes. A rod
    above the table (gap > 0) does not touch it, so both must be zero; a rod pressed into it (gap < 0) gets a normal
    force and friction against its motion."""
    s = settings or ElasticaSettings()
    h, rho, E = 0.002, 1180.0, 4.55e5
    rod_e = ea.CosseratRod.straight_rod(4, np.array([0.0, 0.0, h + gap_m]), np.array([1.0, 0.0, 0.0]),
                                        np.array([0.0, 0.0, 1.0]), 0.02, h, rho, youngs_modulus=E,
                                        shear_modulus=E / 3.0)
    plane = ea.Plane(plane_origin=np.zeros(3), plane_normal=np.array([0.0, 0.0, 1.0]))
    rod_e.velocity_collection[1] = 1e-3
    rod_e.internal_forces[:] = 0.0
    rod_e.external_forces[:] = 0.0
    rod_e.external_forces[2] = -G * rod_e.mass
    before = rod_e.external_forces.copy()
    NodalCoulombStickPlane(s.contact_k_n_m, s.contact_nu_n_s_m, mu, s.dt_s, applied_normal=s.applied_normal,
                           surface_tol=s.contact_surface_tol_m).apply_contact(rod_e, plane)
    f = (rod_e.external_forces - before).sum(axis=1)
    return float(f[2]), float(np.hypot(f[0], f[1]))


class _Clamp(ea.ConstraintBase):
    """Node 0 and element 0 held where they start."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.p = self.system.position_collection[:, 0].copy()
        self.Q = self.system.director_collection[:, :, 0].copy()

    def constrain_values(self, system, time):
        system.position_collection[:, 0] = self.p
        system.director_collection[:, :, 0] = self.Q

    def constrain_rates(self, system, time):
        system.velocity_collection[:, 0] = 0.0
        system.omega_collection[:, 0] = 0.0


def _settled_rod(direction, normal, length, radius, E, rho, n_el, dt, t_end, damping, rotary_scale=1.0):
    sim = _Simulator()
    rod_e = ea.CosseratRod.straight_rod(n_el, np.zeros(3), np.asarray(direction, float), np.asarray(normal, float),
                                        length, radius, rho, youngs_modulus=E, shear_modulus=E / 3.0)
    rotary_inertia_scaled(rod_e, rotary_scale)
    sim.append(rod_e)
    sim.constrain(rod_e).using(_Clamp)
    sim.add_forcing_to(rod_e).using(ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -G]))
    sim.dampen(rod_e).using(ea.AnalyticalLinearDamper, uniform_damping_constant=damping, time_step=dt)
    sim.finalize()
    stepper = ea.PositionVerlet()
    now = np.float64(0.0)
    for _ in range(int(round(t_end / dt))):
        now = stepper.step(sim, now, dt)
    return rod_e


def validate(rod):
    """PyElastica against closed forms with the rod's material: hanging stretch and cantilever deflection."""
    E, rho = rod_material(rod)
    h, L = rod.radius_m, rod.length_m
    out = []
    # a rod hanging from its top: tip displacement rho g L^2 / (2E) (small strain)
    s = ElasticaSettings()
    rod_e = _settled_rod([0, 0, -1], [1, 0, 0], L, h, E, rho, n_el=int(round(L / s.element_length_m)), dt=s.dt_s,
                         t_end=3.0, damping=20.0, rotary_scale=s.rotary_inertia_scale)
    stretch = -rod_e.position_collection[2, -1] - L
    closed = rho * G * L ** 2 / (2 * E)
    out.append((f'hanging rod, stretch at the free end (the replay\'s elements, dt, rotary inertia x'
                f'{s.rotary_inertia_scale:g})', stretch, closed))
    # a horizontal cantilever of 0.5 L_gb under its own weight: tip deflection q L^4 / (8 EI) (w / Lc = 0.8 %);
    # PyElastica's clamp (node 0 and the director of element 0) converges at first order in the element length
    Lc = 0.5 * rod.gravito_bending_length_m
    q = rho * math.pi * h ** 2 * G
    closed_c = q * Lc ** 4 / (8 * E * math.pi * h ** 4 / 4)
    for n_el, dt in ((10, 3e-5), (20, 1.5e-5), (40, 7.5e-6)):            # dt = dl / (2 c)
        rod_c = _settled_rod([1, 0, 0], [0, 0, 1], Lc, h, E, rho, n_el=n_el, dt=dt, t_end=0.6, damping=60.0,
                             rotary_scale=100.0)
        out.append((f'cantilever 0.5 L_gb ({n_el} elements), tip deflection', -rod_c.position_collection[2, -1],
                    closed_c))
    return out


# ---------------------------------------------------------------------------------------------- the table

def read_our_table(path):
    """{(rod, friction, pattern, planner): e_mean_cm} from a deployment_table.md."""
    ours = {}
    if not path.exists():
        return ours
    for line in path.read_text().splitlines():
        m = re.match(r'\| #(\d) \| (\w+) \| (\w+) \| (\w+) \| ([0-9.na]+) \|', line)
        if m and m.group(5) != 'nan':
            ours[(int(m.group(1)), m.group(2), m.group(3), m.group(4))] = float(m.group(5))
    return ours


def main():
    from deployment_table import REF, RODS, all_patterns, published_trajectory
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory
    from rod_deploy.planning.trajectory_io import read_trajectory_csv

    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--validate', action='store_true', help='only the closed-form checks')
    ap.add_argument('--rods', default='3')
    ap.add_argument('--friction', default='medium')
    ap.add_argument('--methods', default='nn,intuitive,published')
    ap.add_argument('--patterns', default='all')
    ap.add_argument('--dt', type=float, default=ElasticaSettings.dt_s)
    ap.add_argument('--element', type=float, default=ElasticaSettings.element_length_m)
    ap.add_argument('--contact-k', type=float, default=ElasticaSettings.contact_k_n_m)
    ap.add_argument('--slip-tol', type=float, default=ElasticaSettings.slip_velocity_tol_m_s)
    ap.add_argument('--contact-tol', type=float, default=ElasticaSettings.contact_surface_tol_m,
                    help='an element touches the table while its centreline is at most this above the contact '
                         'height [m] (PyElastica\'s own value: 1e-4)')
    ap.add_argument('--rotary-scale', type=float, default=ElasticaSettings.rotary_inertia_scale,
                    help='rotary inertia factor (a large one slows the rod\'s rolling on the table: a diagnostic)')
    ap.add_argument('--friction-law', choices=('pyelastica', 'centreline', 'stick'),
                    default=ElasticaSettings.friction_law,
                    help="stick: Coulomb friction on the nodes, stick / slip over the step (NodalCoulombStickPlane, "
                         "no creep); centreline: on the elements with PyElastica's slip-tolerance switch "
                         "(CentrelineCoulombPlane, creeps); pyelastica: PyElastica's anisotropic friction (creeps, "
                         'and rolls sideways)')
    ap.add_argument('--response-normal', action='store_true',
                    help="stick law: bound the friction by PyElastica's plane response alone (on the elements, half to "
                         'each node; the default until the study of the disagreement) instead of the normal force the '
                         'plane applies to the node')
    ap.add_argument('--traj-dir', metavar='DIR',
                    help='read each trajectory from DIR/traj_PATTERN_METHOD_rodK_FRICTION.csv (written by '
                         'deployment_table.py --save-traj; e.g. the method nn_refined) instead of planning it')
    ap.add_argument('--plots', action='store_true')
    ap.add_argument('--tag', default='', help='suffix of the results files')
    ap.add_argument('--merge', nargs='+', metavar='JSON',
                    help='only write one table from the .json files of earlier runs (ours read again)')
    ap.add_argument('--note', default='', help='a paragraph added to the merged table')
    ap.add_argument('--ours', nargs='+', metavar='MD',
                    help="our simulator's deployment tables (later ones override earlier ones); default: "
                         "deployment_table.md in the results folder")
    add_results_argument(ap)
    args = ap.parse_args()
    settings = ElasticaSettings(dt_s=args.dt, element_length_m=args.element, contact_k_n_m=args.contact_k,
                                slip_velocity_tol_m_s=args.slip_tol, rotary_inertia_scale=args.rotary_scale,
                                contact_surface_tol_m=args.contact_tol,
                                friction_law=args.friction_law, applied_normal=not args.response_normal)
    t_all = time.perf_counter()
    checks = []
    def our_tables(out):
        ours = {}
        for f in args.ours or [out.parent / 'deployment_table.md']:
            ours.update(read_our_table(Path(f)))
        return ours

    if args.merge:
        out = results_path(args, f'pyelastica_replay{args.tag}.md')
        ours = our_tables(out)
        rows = [r for f in args.merge for r in json.loads(Path(f).read_text())['rows']]
        pats = all_patterns()
        for r in rows:
            if 'nodes_mm' in r and r['pattern'] in pats:
                r['free_end_shift_mm'] = float(np.linalg.norm(np.array(r['nodes_mm'])[0, :2] -
                                                              1e3 * pats[r['pattern']][0, :2]))
            r['ours_e_mean_cm'] = ours.get((r['rod'], r['friction'], r['pattern'], r['planner']), float('nan'))
        _write(out, rows, [], settings, sum(r['wall_s'] for r in rows))
        if args.note:
            out.write_text(out.read_text() + '\n' + args.note + '\n')
        print(f'results: {out}')
        return
    if args.validate:
        for rod_id in sorted({int(r) for r in args.rods.split(',')}):
            for name, got, want in validate(rod_description_from_dict(RODS[rod_id])):
                checks.append((rod_id, name, got, want))
                print(f'rod #{rod_id} {name}: PyElastica {1e3 * got:.4f} mm, closed form {1e3 * want:.4f} mm '
                      f'({100 * (got / want - 1):+.2f} %)', flush=True)
        _write(results_path(args, f'pyelastica_validation{args.tag}.md'), [], checks, ElasticaSettings(),
               time.perf_counter() - t_all)
        return
    patterns = all_patterns(args.patterns)
    out = results_path(args, f'pyelastica_replay{args.tag}.md')
    ours = our_tables(out)       # (--ours was read only with --merge: a run compared with deployment_table.md)
    rows = []
    for rod_id in (int(r) for r in args.rods.split(',')):
        rod = rod_description_from_dict(RODS[rod_id])
        for fr in args.friction.split(','):
            for method in args.methods.split(','):
                batch, names, failed = [], [], []
                for name, P in patterns.items():
                    if method == 'published' and (rod_id != 3 or not (REF / 'reference_outputs' /
                                                                      f'{name}_traj_NN.txt').exists()):
                        continue
                    saved = Path(args.traj_dir or '.') / f'traj_{name}_{method}_rod{rod_id}_{fr}.csv'
                    try:
                        if args.traj_dir:
                            if not saved.exists():
                                raise ValueError(f'no saved trajectory {saved}')
                            t, p, q = read_trajectory_csv(saved)
                            batch.append((t, p, q, tuple(P[0]) if method == 'published' else None))
                        elif method == 'published':
                            t, p, q = published_trajectory(name)
                            batch.append((t, p, q, tuple(P[0])))
                        else:
                            # the planner told the row's friction (its friction-limited start), as in deployment_table
                            plan = plan_trajectory(P, rod, PlannerSettings(method=method,
                                                                           friction=FRICTION_LEVELS[fr]))
                            batch.append((plan.t, plan.position, plan.quaternion, None))
                        names.append(name)
                    except ValueError as exc:
                        failed.append((name, str(exc)[:90]))
                results, wall = replay_in_elastica(batch, rod, FRICTION_LEVELS[fr], settings) if batch else ([], 0)
                for name, res in zip(names, results):
                    P = patterns[name]
                    e = eq17_error(P, res['deployed_xy'])
                    rows.append({'rod': rod_id, 'friction': fr, 'pattern': name, 'planner': method,
                                 'e_mean_cm': e['e_mean_cm'], 'sigma_cm': e['sigma_cm'], 'coverage': e['coverage'],
                                 'wall_s': wall / len(results), 'note': '',
                                 'nodes_mm': np.round(1e3 * res['nodes'], 3).tolist()})
                    if args.plots:
                        _plot(out.parent / f'elastica_{name}_{method}_rod{rod_id}_{fr}{args.tag}.png', res, P,
                              f'PyElastica: {name}, {method}, rod #{rod_id}, {fr} friction; e_mean '
                              f'{e["e_mean_cm"]:.3f} cm')
                for name, note in failed:
                    rows.append({'rod': rod_id, 'friction': fr, 'pattern': name, 'planner': method,
                                 'e_mean_cm': float('nan'), 'sigma_cm': float('nan'), 'coverage': float('nan'),
                                 'wall_s': 0.0, 'note': note})
                for row in rows:
                    if 'ours_e_mean_cm' in row:
                        continue
                    row['ours_e_mean_cm'] = ours.get((rod_id, fr, row['pattern'], method), float('nan'))
                    print(f"rod #{rod_id} {fr:6s} {row['pattern']:14s} {method:10s} PyElastica e_mean "
                          f"{row['e_mean_cm']:.3f} cm (ours {row['ours_e_mean_cm']:.3f}) sigma {row['sigma_cm']:.3f} "
                          f"coverage {row['coverage']:.2f} {row['note']}", flush=True)
                _write(out, rows, checks, settings, time.perf_counter() - t_all)
    print(f'results: {out}')


def _plot(path, res, pattern, title):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5, 5))
    ax.plot(pattern[:, 0], pattern[:, 1], 'k-', lw=2, label='prescribed')
    ax.plot(res['nodes'][:, 0], res['nodes'][:, 1], '-', color='0.7', lw=1, label='rod (all)')
    ax.plot(res['deployed_xy'][:, 0], res['deployed_xy'][:, 1], 'r-', lw=1.5, label='deployed (PyElastica)')
    ax.plot(res['gripper_path'][:, 0], res['gripper_path'][:, 1], 'b:', lw=1, label='gripper')
    ax.set_aspect('equal')
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _write(out, rows, checks, s, wall):
    lines = ['# Independent replay in PyElastica 1.0.0, `benchmarks/pyelastica_replay.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores; {wall:.0f} s in all. Cosserat rod, element '
             f'{1e3 * s.element_length_m:g} mm, position Verlet dt {s.dt_s:g} s, uniform damping '
             f'{s.damping_per_s:g}/s, rod-plane contact k {s.contact_k_n_m:g} N/m nu {s.contact_nu_n_s_m:g} N s/m '
             f'on the elements within {1e6 * s.contact_surface_tol_m:g} um of the contact height '
             + (f'with Coulomb friction on the centreline (`CentrelineCoulombPlane`: no rolling; static / kinetic '
                f'switch at slip tolerance {s.slip_velocity_tol_m_s:g} m/s)' if s.friction_law == 'centreline' else
                'with Coulomb friction on the nodes\' centreline velocity, stick / slip over the step '
                '(`NodalCoulombStickPlane`: no rolling, no slip tolerance, a sticking node held still; friction '
                + ('bounded by the normal force the plane applies to the node)' if s.applied_normal
                   else "bounded by PyElastica's plane response on the elements, half to each node, "
                        "`--response-normal`)")
                if s.friction_law == 'stick' else
                f'with PyElastica\'s friction (static / kinetic mu, slip tolerance {s.slip_velocity_tol_m_s:g} m/s, '
                f'sideways on the rolling slip)') + f'; hanging {s.hang_settle_s:g} s first, gripper at 0.01 m/s, '
             f'{s.settle_s:g} s still at the end. Eq. 17, N = 50 (ours). "ours": our DER simulator\'s e_mean '
             f'from `deployment_table.md` in the same folder (or the tables given by --ours).', '',
             'Command: `PYTHONPATH=ros_ws/src/rod_deploy .venv-bench/bin/python benchmarks/pyelastica_replay.py '
             + ' '.join(sys.argv[1:]) + '`', '',
             '## Closed forms (`--validate`; the rod material of the table\'s rods)', '',
             '| rod | check | PyElastica mm | closed form mm | rel. error |', '|---|---|---|---|---|']
    for rod_id, name, got, want in checks:
        lines.append(f'| #{rod_id} | {name} | {1e3 * got:.4f} | {1e3 * want:.4f} | {100 * (got / want - 1):+.2f} % |')
    if not rows:
        out.write_text('\n'.join(lines) + '\n')
        return
    lines = lines[:5] + ['', 'The closed-form checks of this set-up: `pyelastica_validation.md`.']
    lines += ['', '## Deployments', '',
              '| rod | friction | pattern | planner | PyElastica e_mean cm | sigma cm | coverage | free end moved mm | '
              'ours e_mean cm | difference cm | wall s (batch / rods) | note |',
              '|---|---|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        d = r['e_mean_cm'] - r['ours_e_mean_cm']
        lines.append(f"| #{r['rod']} | {r['friction']} | {r['pattern']} | {r['planner']} | {r['e_mean_cm']:.3f} | "
                     f"{r['sigma_cm']:.3f} | {r['coverage']:.2f} | {r.get('free_end_shift_mm', float('nan')):.1f} | "
                     f"{r['ours_e_mean_cm']:.3f} | {d:+.3f} | {r['wall_s']:.0f} | {r['note']} |")
    by = {}
    for r in rows:
        if np.isfinite(r['e_mean_cm']):
            by.setdefault(r['planner'], []).append(r['e_mean_cm'])
    lines += ['', '| planner | cases | mean e_mean cm (PyElastica) | min | max |', '|---|---|---|---|---|']
    for m, v in by.items():
        lines.append(f'| {m} | {len(v)} | {np.mean(v):.3f} | {np.min(v):.3f} | {np.max(v):.3f} |')
    out.write_text('\n'.join(lines) + '\n')
    out.with_suffix('.json').write_text(json.dumps({'checks': [list(c) for c in checks], 'rows': rows}, indent=1))


if __name__ == '__main__':
    main()
