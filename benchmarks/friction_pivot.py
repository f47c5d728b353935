"""A closed form for the table friction of both simulators (issue #10): a short straight rod lying on the table,
pushed sideways at one end (or turned by a couple at its ends), the load ramped slowly from zero. Coulomb's answer
for a rigid rod of weight W: it stays still until the load reaches

    end force F, perpendicular to the rod:  F_c = (sqrt(2) - 1) mu W,  turning about the point L / sqrt(2) from the
                                            pushed end (friction changes side there: moment and force balance);
    couple P at the two ends (+P, -P):      P_c = mu W / 4,             turning about the middle,

and the discrete rods (node weights m_i g, half an element at each end) have the same answers with sums for the
integrals: F_c = min_c mu g sum m_i |x_i - c| / c, P_c = min_c mu g sum m_i |x_i - c| / L. A rod of rod #3's material
(L_gb 3.4 cm) 2 cm long bends by about 0.1 mm under F_c: rigid at the scale measured (breakaway: the pushed end
0.5 mm from where it was when the load came on).

    PYTHONPATH=ros_ws/src/rod_deploy .venv-bench/bin/python benchmarks/friction_pivot.py [--mu 0.5,1.0] \
        [--commit-results]

Both simulators as the deployments use them: PyElastica with the replay's stick / slip law on the nodes
(``NodalCoulombStickPlane``, friction bounded by the normal force the plane applies to the node; rotary inertia x100,
damping 2/s, contact k 200 N/m nu 0.1 N s/m), our DER (implicit Euler dt 0.02 s, friction regularised below 1e-6 m/s,
damping 2/s); the same 2 mm elements / edges, the load on the same nodes. Reported: the load ratio (load / the discrete
closed form) at breakaway, and where the rod turns (the point of zero sideways displacement when the pushed end has
moved 2 mm, from the pushed end, over L).
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pyelastica_replay import NodalCoulombStickPlane, _Simulator, ea, rod_material, rotary_inertia_scaled  # noqa: E402
from results_dir import add_results_argument, results_path  # noqa: E402

from rod_deploy.deployment.simulate import DEFAULT_FRICTION_VELOCITY_M_S, material_parameters  # noqa: E402
from rod_deploy.physics.der_simulator import DiscreteElasticRod  # noqa: E402
from rod_deploy.planning.rod_description import rod_description_from_dict  # noqa: E402

G = 9.81
ROD3 = {'length': 0.89, 'radius': 0.002, 'L_gb': 0.034}
LENGTH_M = 0.02
ELEMENT_M = 0.002
DAMPING = 2.0
SETTLE_S = 0.3
RAMP_S = 8.0           # load from 0 to RAMP_TOP x the closed form over this time
RAMP_TOP = 1.6
BREAKAWAY_M = 5e-4     # the pushed end this far from where it was when the load came on
PIVOT_AT_M = 2e-3      # the turning point read when the pushed end has moved this far
RECORD_S = 0.01


def rod3():
    return rod_description_from_dict(ROD3)


def straight_nodes():
    n = int(round(LENGTH_M / ELEMENT_M))
    x = np.linspace(0.0, LENGTH_M, n + 1)
    return np.column_stack([x, np.zeros_like(x), np.full_like(x, rod3().radius_m)])


def closed_forms(x, m, mu):
    """(F_c, P_c) of the discrete rigid rod (nodes at x, masses m) and of the continuous one."""
    cs = np.linspace(1e-6, x[-1], 20001)
    S = np.array([np.sum(m * np.abs(x - c)) for c in cs])
    F_d = mu * G * np.min(S / cs)
    P_d = mu * G * np.min(S) / x[-1]
    W = G * np.sum(m)
    return F_d, P_d, (math.sqrt(2) - 1) * mu * W, mu * W / 4


def load_vector(kind, n_nodes, P):
    """(n_nodes, 3) sideways forces: 'force' P at node 0, 'couple' +P at node 0 and -P at the last node."""
    f = np.zeros((n_nodes, 3))
    f[0, 1] = P
    if kind == 'couple':
        f[-1, 1] = -P
    return f


def ramp(t):
    return RAMP_TOP * min(max(t - SETTLE_S, 0.0) / RAMP_S, 1.0)


class _RampedLoad(ea.NoForces):
    def __init__(self, unit, **kwargs):
        super().__init__()
        self.unit = np.asarray(unit, float)          # (3, n) forces at ramp 1

    def apply_forces(self, system, time=0.0):
        system.external_forces += ramp(float(time)) * self.unit


def elastica_run(kind, mu, P_unit, dt=5e-5):
    rod = rod3()
    E, rho = rod_material(rod)
    nodes0 = straight_nodes()
    n_el = len(nodes0) - 1
    sim = _Simulator()
    plane = ea.Plane(plane_origin=np.zeros(3), plane_normal=np.array([0.0, 0.0, 1.0]))
    sim.append(plane)
    rod_e = ea.CosseratRod.straight_rod(n_el, nodes0[0], np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]),
                                        LENGTH_M, rod.radius_m, rho, youngs_modulus=E, shear_modulus=E / 3.0)
    rotary_inertia_scaled(rod_e, 100.0)
    sim.append(rod_e)
    sim.add_forcing_to(rod_e).using(ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -G]))
    sim.add_forcing_to(rod_e).using(_RampedLoad, unit=load_vector(kind, n_el + 1, P_unit).T)
    sim.detect_contact_between(rod_e, plane).using(NodalCoulombStickPlane, k=200.0, nu=0.1, mu=mu, dt=dt,
                                                   applied_normal=True)
    sim.dampen(rod_e).using(ea.AnalyticalLinearDamper, uniform_damping_constant=DAMPING, time_step=dt)
    sim.finalize()
    stepper = ea.PositionVerlet()
    now = np.float64(0.0)
    every = int(round(RECORD_S / dt))
    rec = []
    for k in range(int(math.ceil((SETTLE_S + RAMP_S) / dt))):
        now = stepper.step(sim, now, dt)
        if (k + 1) % every == 0:
            rec.append((float(now), rod_e.position_collection.T.copy()))
    return rec, np.asarray(rod_e.mass, float)


def der_run(kind, mu, P_unit, dt=0.02):
    rod = rod3()
    params = material_parameters(rod, mu, DAMPING, DEFAULT_FRICTION_VELOCITY_M_S)
    model = DiscreteElasticRod(straight_nodes(), params, d1_first=np.array([0.0, 0.0, 1.0]))
    base = model.gravity_force.copy()
    unit = np.zeros(model.ndof)
    for i, f in enumerate(load_vector(kind, model.n_edges + 1, P_unit)):
        unit[model.node_dof(i)] = f
    rec = []
    for k in range(int(round((SETTLE_S + RAMP_S) / dt))):
        now = (k + 1) * dt
        model.gravity_force = base + ramp(now) * unit      # implicit Euler: the load at the step's end
        model.step(dt)
        rec.append((now, model.nodes.copy()))
    return rec, np.asarray(model.node_mass, float)


def breakaway(rec):
    """(load ratio at breakaway, turning point / L) from the recorded nodes."""
    t_on = [p for t, p in rec if t <= SETTLE_S + 1e-9][-1]
    ratio, pivot = float('nan'), float('nan')
    for t, p in rec:
        d = p[:, 1] - t_on[:, 1]
        if np.isnan(ratio) and abs(d[0]) >= BREAKAWAY_M:
            ratio = ramp(t)
        if abs(d[0]) >= PIVOT_AT_M:
            k = np.nonzero(np.sign(d) != np.sign(d[0]))[0]
            if len(k):
                j = k[0]
                pivot = (p[j - 1, 0] + (p[j, 0] - p[j - 1, 0]) * d[j - 1] / (d[j - 1] - d[j]) - t_on[0, 0]) / LENGTH_M
            break
    return ratio, pivot


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--mu', default='0.5,1.0')
    ap.add_argument('--tag', default='')
    add_results_argument(ap)
    args = ap.parse_args()
    wall = time.perf_counter()
    rows = []
    nodes = straight_nodes()
    m = material_parameters(rod3(), 0.5, DAMPING).rho_A * ELEMENT_M * np.r_[0.5, np.ones(len(nodes) - 2), 0.5]
    for mu in (float(v) for v in args.mu.split(',')):
        F_d, P_d, F_cont, P_cont = closed_forms(nodes[:, 0], m, mu)
        for kind, P_c, want_pivot in (('force', F_d, 1 / math.sqrt(2)), ('couple', P_d, 0.5)):
            for name, runner in (('PyElastica (stick / slip on the nodes)', elastica_run), ('our DER', der_run)):
                cpu = time.process_time()
                rec, masses = runner(kind, mu, P_c)
                cpu = time.process_time() - cpu
                if not np.allclose(masses, m, rtol=1e-6):
                    raise SystemExit(f'friction_pivot: {name} node masses {masses} differ from {m}')
                ratio, pivot = breakaway(rec)
                rows.append((mu, kind, name, 1e3 * P_c, 1e3 * (F_cont if kind == 'force' else P_cont), ratio, pivot,
                             want_pivot, cpu))
                print(f'mu {mu} {kind:6s} {name}: breakaway at {ratio:.3f} x {1e3 * P_c:.4f} mN, turning point '
                      f'{pivot:.3f} L (rigid {want_pivot:.3f}), CPU {cpu:.0f} s', flush=True)
    out = results_path(args, f'friction_pivot{args.tag}.md')
    lines = ['# A straight rod pushed sideways on the table: Coulomb\'s closed form in both simulators, '
             '`benchmarks/friction_pivot.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores (load {os.getloadavg()[0]:.1f} at the end); '
             f'{time.perf_counter() - wall:.0f} s in all. Rod #3\'s material, {1e2 * LENGTH_M:g} cm long, '
             f'{1e3 * ELEMENT_M:g} mm elements / edges, damping {DAMPING:g}/s; the load ramped from 0 to {RAMP_TOP:g} x '
             f'the discrete closed form over {RAMP_S:g} s after {SETTLE_S:g} s of settling. Breakaway: the pushed '
             f'end {1e3 * BREAKAWAY_M:g} mm from where it was; turning point: where the sideways displacement '
             f'changes sign when the pushed end has moved {1e3 * PIVOT_AT_M:g} mm (from the pushed end, / L). '
             'See the script\'s docstring.', '',
             '| mu | load | simulator | closed form (discrete) mN | closed form (continuous) mN | breakaway / closed form | '
             'turning point / L | rigid turning point / L | CPU s |', '|---|---|---|---|---|---|---|---|---|']
    for mu, kind, name, Pd, Pc, r, piv, wp, cpu in rows:
        lines.append(f'| {mu:g} | {"end force" if kind == "force" else "couple at the ends"} | {name} | {Pd:.4f} | '
                     f'{Pc:.4f} | {r:.3f} | {piv:.3f} | {wp:.3f} | {cpu:.0f} |')
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


if __name__ == '__main__':
    main()
