"""Canonical friction cases with clear physical answers, run in BOTH simulators (our DER and PyElastica 1.0.0), to
find why the independent replay disagrees with ours on curved patterns (issue #10 item 5).

    make bench-env
    PYTHONPATH=ros_ws/src/rod_deploy .venv-bench/bin/python benchmarks/friction_canonical.py [--commit-results]

Rod #3's material (L_gb 3.4 cm, radius 2 mm, density 1180 kg/m^3), medium friction mu = 0.5, viscous damping
c = 2/s in both (as in the deployment replays).

(b) A straight rod (0.2 m, along x) at rest on the table; after 0.3 s of settling, a uniform in-plane body force
    a_F per unit mass, along the rod's axis or sideways, F / (mu N) = a_F / (mu g) = 0.5 (must stick: Coulomb's
    answer is no motion at all) or 1.5 (must slide: x(t) = a/c (t - (1 - exp(-c t)) / c), a = a_F - mu g).
    Reported: the mean displacement of the nodes after 2 s of load.
(a) A rod (0.3 m) laid at rest in an exact circular arc of curvature kappa = 10 /m (no natural curvature), both
    ends free, released at t = 0. A free end carries no moment, so the curvature relaxes near each end until
    friction over the relaxed length supplies EI kappa: with the whole friction mu rho A g acting sideways on a
    length l, f l^2 / 2 = EI kappa, l* = sqrt(2 EI kappa / (mu rho A g)) (= 2 L_gb sqrt(kappa L_gb / mu); 5.6 cm
    here). Under Coulomb friction the motion then STOPS: the end's displacement at 3 s and at 10 s must be the same
    (any growth is creep). Reported: the end's displacement at 1, 3, 10 s and the relaxed length at 10 s (from the
    end to where the curvature first reaches 90 % of kappa).

Set-ups compared: PyElastica as ``pyelastica_replay.py`` used it before (its own friction law
``RodPlaneContactWithAnisotropicFriction``: 1 cm elements, rotary inertia x100, dt 3e-4 s, slip tolerance 1e-4 m/s)
and variants (rotary inertia x1 with dt 1e-4 s; slip tolerance 1e-6 m/s); PyElastica with Coulomb friction on the
centreline (``CentrelineCoulombPlane``, the replay's default now), also with 5 mm elements and with damping 20/s (a
diagnostic: the release transient damped); our DER (5 mm edges, implicit Euler dt 0.02 s) with its friction
regularisation velocity 1e-4 m/s (the deployments') and smaller, and with dt 0.002 s.
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pyelastica_replay import (CentrelineCoulombPlane, NodalCoulombStickPlane, _Simulator, ea,  # noqa: E402
                               rod_material, rotary_inertia_scaled)
from results_dir import add_results_argument, results_path  # noqa: E402

from rod_deploy.deployment.simulate import material_parameters  # noqa: E402
from rod_deploy.physics.der_simulator import DiscreteElasticRod  # noqa: E402
from rod_deploy.planning.rod_description import rod_description_from_dict  # noqa: E402

G = 9.81
ROD3 = {'length': 0.89, 'radius': 0.002, 'L_gb': 0.034}
MU = 0.5
DAMPING = 2.0
SETTLE_S = 0.3


@dataclass(frozen=True)
class ElasticaCase:
    name: str
    rotary_scale: float = 100.0
    dt_s: float = 3e-4
    slip_tol: float = 1e-4
    element_m: float = 0.01
    friction_law: str = 'pyelastica'    # or 'centreline' (CentrelineCoulombPlane: no rolling), 'stick'
    #                                     (NodalCoulombStickPlane: no rolling, stick / slip over the step)
    damping_per_s: float = DAMPING
    only_a: bool = False                # a diagnostic of case (a) only


@dataclass(frozen=True)
class DerCase:
    name: str
    friction_velocity: float = 1e-4
    edge_m: float = 0.005
    dt_s: float = 0.02


ELASTICA_CASES = [ElasticaCase('PyElastica as in the replay (rotary x100, dt 3e-4, slip tol 1e-4)'),
                  ElasticaCase('PyElastica, rotary inertia x1 (dt 1e-4)', rotary_scale=1.0, dt_s=1e-4),
                  ElasticaCase('PyElastica, rotary x100, slip tol 1e-6', slip_tol=1e-6),
                  ElasticaCase('PyElastica, centreline Coulomb (no rolling; rotary x100, slip tol 1e-4)',
                               friction_law='centreline'),
                  ElasticaCase('PyElastica, centreline Coulomb, slip tol 1e-5', friction_law='centreline',
                               slip_tol=1e-5),
                  ElasticaCase('PyElastica, centreline Coulomb, 5 mm elements (dt 1.5e-4)', friction_law='centreline',
                               element_m=0.005, dt_s=1.5e-4, only_a=True),
                  ElasticaCase('PyElastica, centreline Coulomb, damping 20/s (the release transient damped)',
                               friction_law='centreline', damping_per_s=20.0, only_a=True),
                  ElasticaCase('PyElastica, nodal Coulomb stick / slip (no rolling, no slip tolerance; rotary x100)',
                               friction_law='stick'),
                  ElasticaCase('PyElastica, nodal Coulomb stick / slip, 5 mm elements (dt 1.5e-4)',
                               friction_law='stick', element_m=0.005, dt_s=1.5e-4, only_a=True)]
DER_CASES = [DerCase('our DER, friction regularisation 1e-4 m/s (deployments)'),
             DerCase('our DER, regularisation 1e-5 m/s', friction_velocity=1e-5),
             DerCase('our DER, regularisation 1e-6 m/s', friction_velocity=1e-6),
             DerCase('our DER, regularisation 1e-5 m/s, dt 0.002 s (less numerical damping)', friction_velocity=1e-5,
                     dt_s=0.002)]


def rod3():
    return rod_description_from_dict(ROD3)


# ------------------------------------------------------------------------------------------------ PyElastica

class _BodyForce(ea.NoForces):
    """A uniform in-plane body force (per unit mass) switched on at ``t_on``."""

    def __init__(self, acc, t_on):
        super().__init__()
        self.acc = np.asarray(acc, float)
        self.t_on = t_on

    def apply_forces(self, system, time=0.0):
        if time >= self.t_on:
            system.external_forces += system.mass[None, :] * self.acc[:, None]


class _Probe(ea.CallBackBaseClass):
    def __init__(self, times, store):
        super().__init__()
        self.times = list(times)
        self.store = store

    def make_callback(self, system, time, current_step):
        if self.times and time >= self.times[0] - 1e-9:
            d1, d3 = system.director_collection[0].T, system.director_collection[2].T
            lateral = np.cross(d3, [0.0, 0.0, 1.0])
            roll = np.degrees(np.arctan2(np.sum(d1 * lateral, axis=1), d1[:, 2]))   # 0: d1 still vertical
            self.store.append((self.times.pop(0), system.position_collection.copy(), float(np.median(roll))))


def elastica_run(case: ElasticaCase, nodes0, t_end, body_acc=(0, 0, 0), t_on=0.0, probe_times=()):
    """Rod #3's material laid along the polyline ``nodes0`` (at z = h, at rest, no rest curvature), on the table
    with PyElastica's rod-plane contact and anisotropic friction (mu the same in all directions), gravity, damping.
    Returns [(t, positions (3, n+1))] at ``probe_times``."""
    rod = rod3()
    E, rho = rod_material(rod)
    h = rod.radius_m
    n_el = len(nodes0) - 1
    seg = np.diff(nodes0, axis=0)
    length = float(np.sum(np.linalg.norm(seg, axis=1)))
    sim = _Simulator()
    plane = ea.Plane(plane_origin=np.zeros(3), plane_normal=np.array([0.0, 0.0, 1.0]))
    sim.append(plane)
    rod_e = ea.CosseratRod.straight_rod(n_el, nodes0[0], seg[0] / np.linalg.norm(seg[0]), np.array([0.0, 0.0, 1.0]),
                                        length, h, rho, youngs_modulus=E, shear_modulus=E / 3.0)
    rod_e.position_collection[:] = nodes0.T
    t = seg / np.linalg.norm(seg, axis=1)[:, None]
    d1 = np.tile([0.0, 0.0, 1.0], (n_el, 1))
    d2 = np.cross(t, d1)
    rod_e.director_collection[:] = np.stack([d1, d2, t], axis=1).transpose(1, 2, 0)   # rows d1, d2, d3
    rotary_inertia_scaled(rod_e, case.rotary_scale)
    sim.append(rod_e)
    mu = np.array([MU, MU, MU])
    sim.add_forcing_to(rod_e).using(ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -G]))
    sim.add_forcing_to(rod_e).using(_BodyForce, acc=body_acc, t_on=t_on)
    if case.friction_law == 'centreline':
        sim.detect_contact_between(rod_e, plane).using(CentrelineCoulombPlane, k=200.0, nu=0.1, mu=MU,
                                                       slip_velocity_tol=case.slip_tol)
    elif case.friction_law == 'stick':
        sim.detect_contact_between(rod_e, plane).using(NodalCoulombStickPlane, k=200.0, nu=0.1, mu=MU,
                                                       dt=case.dt_s)
    else:
        sim.detect_contact_between(rod_e, plane).using(
            ea.RodPlaneContactWithAnisotropicFriction, k=200.0, nu=0.1, slip_velocity_tol=case.slip_tol,
            static_mu_array=mu, kinetic_mu_array=mu)
    sim.dampen(rod_e).using(ea.AnalyticalLinearDamper, uniform_damping_constant=case.damping_per_s,
                            time_step=case.dt_s)
    store = []
    sim.collect_diagnostics(rod_e).using(_Probe, times=probe_times, store=store)
    sim.finalize()
    stepper = ea.PositionVerlet()
    now = np.float64(0.0)
    for _ in range(int(math.ceil(t_end / case.dt_s)) + 1):
        now = stepper.step(sim, now, case.dt_s)
    if not np.all(np.isfinite(rod_e.position_collection)):
        raise RuntimeError(f'{case.name}: diverged')
    return [(tt, p.T, roll) for tt, p, roll in store]


# ------------------------------------------------------------------------------------------------ our DER

def der_run(case: DerCase, nodes0, t_end, body_acc=(0, 0, 0), t_on=0.0, probe_times=()):
    """The same in our DER: nodes0 at z = h, at rest; a body force per unit mass switched on at ``t_on``."""
    rod = rod3()
    params = material_parameters(rod, MU, DAMPING, case.friction_velocity)
    model = DiscreteElasticRod(nodes0, params, d1_first=np.array([0.0, 0.0, 1.0]))
    extra = np.zeros(model.ndof)
    for i, m in enumerate(model.node_mass):
        extra[model.node_dof(i)] = m * np.asarray(body_acc, float)
    times = list(probe_times)
    out, on = [], False
    steps = int(round(t_end / case.dt_s))
    for k in range(steps):
        now = (k + 1) * case.dt_s
        if not on and now > t_on + 1e-12:
            model.gravity_force = model.gravity_force + extra
            on = True
        model.step(case.dt_s)
        if times and now >= times[0] - 1e-9:
            out.append((times.pop(0), model.nodes.copy(), float('nan')))
    return out


# ------------------------------------------------------------------------------------------------ cases

def straight_nodes(length, dl, h):
    n = int(round(length / dl))
    x = np.linspace(0.0, length, n + 1)
    return np.column_stack([x, np.zeros_like(x), np.full_like(x, h)])


def arc_nodes(length, dl, kappa, h):
    n = int(round(length / dl))
    s = np.linspace(-length / 2, length / 2, n + 1)
    # a polygon inscribed in the circle (the discrete curvature of both models is then uniform)
    return np.column_stack([np.sin(kappa * s) / kappa, (1 - np.cos(kappa * s)) / kappa, np.full_like(s, h)])


def sliding_closed_form(ratio, t):
    """Mean displacement after t s of a uniform body force ratio * mu g (per unit mass) on a rod on the table."""
    if ratio <= 1.0:
        return 0.0
    a = (ratio - 1.0) * MU * G
    c = DAMPING
    return a / c * (t - (1 - math.exp(-c * t)) / c)


def case_b(runner, case, dl):
    rows = []
    h = rod3().radius_m
    t_load = 2.0
    for direction, vec in (('axial', np.array([1.0, 0.0, 0.0])), ('sideways', np.array([0.0, 1.0, 0.0]))):
        for ratio in (0.5, 1.5):
            nodes0 = straight_nodes(0.2, dl, h)
            acc = ratio * MU * G * vec
            res = runner(case, nodes0, SETTLE_S + t_load, acc, SETTLE_S, probe_times=(SETTLE_S, SETTLE_S + t_load))
            (_, p_on, _), (_, p_end, _) = res
            moved = float(np.mean((p_end - p_on) @ vec))
            rows.append((direction, ratio, moved, sliding_closed_form(ratio, t_load)))
    return rows


def relaxed_length(nodes, kappa):
    """Arc length from node 0 to where the discrete curvature (turning angle / Voronoi length) first reaches
    90 % of kappa."""
    p = nodes[:, :2]
    e = np.diff(p, axis=0)
    le = np.linalg.norm(e, axis=1)
    ang = np.arctan2(e[:-1, 0] * e[1:, 1] - e[:-1, 1] * e[1:, 0], np.sum(e[:-1] * e[1:], axis=1))
    k = np.abs(ang) / (0.5 * (le[1:] + le[:-1]))
    s = np.cumsum(le)[:-1]
    hit = np.flatnonzero(k >= 0.9 * kappa)
    return float(s[hit[0]]) if len(hit) else float('nan')


def case_a(runner, case, dl, kappa=10.0, length=0.3):
    h = rod3().radius_m
    nodes0 = arc_nodes(length, dl, kappa, h)
    probes = (1.0, 3.0, 10.0)
    res = runner(case, nodes0, probes[-1], probe_times=probes)
    moved = [float(np.linalg.norm(p[0, :2] - nodes0[0, :2])) for _, p, _ in res]
    centre = float(np.linalg.norm(res[-1][1][len(nodes0) // 2, :2] - nodes0[len(nodes0) // 2, :2]))
    return moved, relaxed_length(res[-1][1], kappa), centre, res[-1][2]


def l_star(kappa):
    rod = rod3()
    p = material_parameters(rod, MU, DAMPING)
    return math.sqrt(2 * p.EI * kappa / (MU * p.rho_A * G))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--only', choices=('a', 'b'), default=None)
    ap.add_argument('--cases', default=None, help='only the set-ups whose name contains this text')
    ap.add_argument('--tag', default='', help='suffix of the results file')
    add_results_argument(ap)
    args = ap.parse_args()
    wall = time.perf_counter()
    runs = [(c, elastica_run, c.element_m) for c in ELASTICA_CASES] + [(c, der_run, c.edge_m) for c in DER_CASES]
    if args.cases:
        runs = [r for r in runs if args.cases in r[0].name]
    b_rows, a_rows = [], []
    for case, runner, dl in runs:
        t0 = time.perf_counter()
        if args.only != 'a' and not getattr(case, 'only_a', False):
            try:
                rows = case_b(runner, case, dl)
            except RuntimeError as exc:          # an explicit step beyond its stability bound: said in the table
                print(f'(b) {exc}', flush=True)
                rows = [('diverged', float('nan'), float('nan'), float('nan'))]
            for row in rows:
                b_rows.append((case.name,) + row)
                print(f'(b) {case.name}: {row[0]} F/muN {row[1]}: moved {1e3 * row[2]:.3f} mm '
                      f'(Coulomb {1e3 * row[3]:.3f} mm)', flush=True)
        if args.only != 'b':
            moved, lr, centre, roll = case_a(runner, case, dl)
            a_rows.append((case.name, moved, lr, centre, roll))
            print(f'(a) {case.name}: end moved {[round(1e3 * m, 2) for m in moved]} mm at 1/3/10 s, relaxed length '
                  f'{1e3 * lr:.1f} mm (l* {1e3 * l_star(10.0):.1f} mm), middle moved {1e3 * centre:.2f} mm, '
                  f'median roll {roll:.1f} deg', flush=True)
        print(f'    ({time.perf_counter() - t0:.0f} s)', flush=True)
    out = results_path(args, f'friction_canonical{args.tag}.md')
    lines = ['# Canonical friction cases in both simulators, `benchmarks/friction_canonical.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores; {time.perf_counter() - wall:.0f} s in all. '
             f'Rod #3 material, mu = {MU}, damping {DAMPING:g}/s. See the script\'s docstring for the set-ups.', '']
    if b_rows:
        lines += ['## (b) straight rod on the table, uniform in-plane body force for 2 s', '',
                  '| simulator | direction | F / (mu N) | mean displacement mm | Coulomb mm |', '|---|---|---|---|---|']
        lines += [f'| {n} | {d} | {r:g} | {1e3 * m:.3f} | {1e3 * c:.3f} |' for n, d, r, m, c in b_rows]
    if a_rows:
        lines += ['', '## (a) arc of curvature 10 /m, 0.3 m, released at rest, both ends free', '',
                  f'Relaxed-length scale l* = sqrt(2 EI kappa / (mu rho A g)) = {1e3 * l_star(10.0):.1f} mm. '
                  'Coulomb: the end stops once friction holds the rest (3 s = 10 s).', '',
                  '| simulator | end moved at 1 s mm | 3 s | 10 s | relaxed length at 10 s mm | '
                  'middle of the arc moved at 10 s mm | elements rolled about their axis at 10 s (median) deg |',
                  '|---|---|---|---|---|---|---|']
        lines += [f'| {n} | {1e3 * m[0]:.2f} | {1e3 * m[1]:.2f} | {1e3 * m[2]:.2f} | {1e3 * lr:.1f} | '
                  f'{1e3 * c:.2f} | '
                  f'{"" if not np.isfinite(r) else f"{r:.1f}"} |' for n, m, lr, c, r in a_rows]
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


if __name__ == '__main__':
    main()
