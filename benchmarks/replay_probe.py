"""Diagnostic: one trajectory replayed in PyElastica (``pyelastica_replay``) and/or our DER with the rod's nodes kept
every second, so that the two simulators can be compared over time (free end, laid rod), not only at the end.

    PYTHONPATH=ros_ws/src/rod_deploy .venv-bench/bin/python benchmarks/replay_probe.py --sim elastica \
        --pattern circle --method published --out /tmp/probe_circle_el.npz [--set dt_s=1.5e-4 ...]
    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/replay_probe.py --sim der --pattern circle ...

Writes an .npz: times, nodes (k, n, 3), pattern, e_mean_cm, t_release_s, cpu_s; and the table's normal force on
every node at the snapshots (normal_times, normal_law: the one the friction law bounds the friction by, normal_plane:
the one the table applies; in our DER both are the contact penalty's; in PyElastica with the stick law, normal_law is
PyElastica's plane response on the elements, half to each node, unless ``--set applied_normal=1``).
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def load_case(pattern, method, rod, traj=None, pattern_file=None):
    from deployment_table import all_patterns, published_trajectory
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory
    if pattern_file:                 # a pattern file (e.g. the acceptance rehearsal's), its trajectory given by --traj
        from rod_deploy.planning.pattern_input import load_pattern
        if not traj:
            raise SystemExit('replay_probe: error: --pattern-file needs --traj (the trajectory to replay)')
        P = load_pattern(pattern_file)
    else:
        P = all_patterns(pattern)[pattern]
    if traj:                         # a saved trajectory (deployment_table.py --save-traj) starting at a hanging pose
        from rod_deploy.planning.trajectory_io import read_trajectory_csv
        return P, (*read_trajectory_csv(traj), None)
    if method == 'published':
        t, p, q = published_trajectory(pattern)
        return P, (t, p, q, tuple(P[0]))
    plan = plan_trajectory(P, rod, PlannerSettings(method=method))
    return P, (plan.t, plan.position, plan.quaternion, None)


_YES, _NO = ('1', 'true', 'yes', 'on'), ('0', 'false', 'no', 'off')


def with_settings(settings, sets):
    """The dataclass ``settings`` with the ``--set`` overrides {name: text}: a number in the field's type, a yes/no
    field from 1/true/yes/on or 0/false/no/off (``bool('0')`` would be True); an unknown name, a yes/no text that is
    neither, or a field of another type (None, a tuple) is an error."""
    import dataclasses
    fields = {f.name for f in dataclasses.fields(settings)}
    for name, text in sets.items():
        if name not in fields:
            raise SystemExit(f'replay_probe: error: --set {name}: no such setting in {type(settings).__name__} '
                             f'({", ".join(sorted(fields))})')
        typ = type(getattr(settings, name))
        if typ is bool:
            if text.lower() not in _YES + _NO:
                raise SystemExit(f'replay_probe: error: --set {name}={text}: a yes/no setting takes 1/0, true/false, '
                                 'yes/no or on/off')
            value = text.lower() in _YES
        elif typ in (int, float, str):
            try:
                value = typ(text)
            except ValueError:
                raise SystemExit(f'replay_probe: error: --set {name}={text}: not a {typ.__name__}') from None
        else:
            raise SystemExit(f'replay_probe: error: --set {name}: a {typ.__name__} setting cannot be given here')
        settings = dataclasses.replace(settings, **{name: value})
    return settings


def friction_coefficient(text, levels):
    """A friction level's name (``levels``) or a positive number."""
    if text in levels:
        return levels[text]
    try:
        mu = float(text)
    except ValueError:
        mu = float('nan')
    if not mu > 0 or not math.isfinite(mu):
        raise SystemExit(f'replay_probe: error: --friction {text}: give {", ".join(levels)} or a positive number')
    return mu


def run_elastica(case, rod, friction, sets, every):
    from pyelastica_replay import ElasticaSettings, replay_in_elastica
    s = with_settings(ElasticaSettings(), sets)
    normals = []
    if s.friction_law == 'stick':
        # record the stick law's normal force per node at every snapshot: as the law takes it and as the plane
        # applies it (the contact forces computed once more on a copy; the law itself runs unchanged)
        import pyelastica_replay as pr

        class Recording(pr.NodalCoulombStickPlane):
            def apply_contact(self, system_one, system_two, time=np.float64(0.0)):
                if int(round(float(time) / s.dt_s)) % int(round(every / s.dt_s)) == 0 and time > 0:
                    ext = system_one.external_forces.copy()
                    n_mag, no_contact = pr._calculate_contact_forces_rod_plane(
                        system_two.origin, system_two.normal, self.surface_tol, self.k, self.nu,
                        system_one.radius, system_one.mass, system_one.position_collection,
                        system_one.velocity_collection, system_one.internal_forces, ext)
                    in_contact = np.ones(len(n_mag))
                    in_contact[no_contact] = 0.0
                    n_law = np.zeros(len(n_mag) + 1)
                    n_law[:-1] += 0.5 * in_contact * n_mag
                    n_law[1:] += 0.5 * in_contact * n_mag
                    n_plane = np.maximum(system_two.normal @ (ext - system_one.external_forces), 0.0)
                    normals.append((float(time), n_law if not self.applied_normal else n_plane, n_plane))
                super().apply_contact(system_one, system_two, time)

        pr.NodalCoulombStickPlane = Recording
    res, _ = replay_in_elastica([case], rod, friction, s, progress=False, snapshot_every_s=every)
    r = res[0]
    times = np.array([t for t, _ in r['snapshots']]) - s.hang_settle_s   # replay time (0 = leaves hanging pose)
    nodes = np.array([n for _, n in r['snapshots']])
    extra = {}
    if normals:
        extra = dict(normal_times=np.array([t for t, _, _ in normals]) - s.hang_settle_s,
                     normal_law=np.array([a for _, a, _ in normals]), normal_plane=np.array([b for _, _, b in normals]))
    return times, nodes, r['deployed_xy'], r['t_release_s'] - s.hang_settle_s, repr(s), extra


def run_der(case, rod, friction, sets, every):
    import rod_deploy.deployment.simulate as sim
    s = with_settings(sim.SimulationSettings(friction=friction, start_xy=case[3]), sets)
    rec = {'k': 0, 'times': [], 'nodes': [], 'normals': []}
    n_every = int(round(every / s.dt_s))

    class Recording(sim.DiscreteElasticRod):
        def step(self, dt):
            out = super().step(dt)
            rec['k'] += 1
            if rec['k'] % n_every == 0:
                rec['times'].append(rec['k'] * dt)
                rec['nodes'].append(self.nodes.copy())
                _, fc, _ = self.contact(self.state.q, hessian=False)      # the table's normal force per node
                rec['normals'].append(fc[2::4].copy())
            return out

    sim.DiscreteElasticRod = Recording
    t, p, q, _ = case
    res = sim.simulate_deployment(t, p, q, rod, s)
    sched = sim.replay_schedule(t, p, q, rod, case[3])
    return (np.array(rec['times']), np.array(rec['nodes']), res.deployed_xy, sched.t_release, repr(s),
            dict(normal_times=np.array(rec['times']), normal_law=np.array(rec['normals']),
                 normal_plane=np.array(rec['normals'])))


def main():
    from deployment_table import RODS
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.deployment.simulate import FRICTION_LEVELS
    from rod_deploy.planning.rod_description import rod_description_from_dict
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--sim', choices=('elastica', 'der'), required=True)
    ap.add_argument('--pattern', default='circle')
    ap.add_argument('--method', default='published')
    ap.add_argument('--rod', type=int, default=3)
    ap.add_argument('--friction', default='medium',
                    help='low / medium / high (0.2 / 0.5 / 1.0) or a coefficient (e.g. 5 for the no-slip limit)')
    ap.add_argument('--every', type=float, default=1.0, help='snapshot period [simulated s]')
    ap.add_argument('--set', nargs='*', default=[], help='settings overrides name=value')
    ap.add_argument('--pattern-file', help='score against this pattern file instead of --pattern (needs --traj)')
    ap.add_argument('--traj', help='replay this trajectory CSV (starting at a hanging pose) instead of planning one')
    ap.add_argument('--lead-in-only', action='store_true',
                    help="replay only the trajectory's lead-in (the free end held all along; a short run for the "
                         "direction in which the hanging rod's bottom buckles)")
    ap.add_argument('--out', required=True)
    args = ap.parse_args()
    rod = rod_description_from_dict(RODS[args.rod])
    P, case = load_case(args.pattern, args.method, rod, args.traj, args.pattern_file)
    if args.lead_in_only:
        from rod_deploy.deployment.simulate import replay_schedule
        t, p, q, start = case
        n = replay_schedule(t, p, q, rod, start).lead_in_rows
        k = n if start is None else max(n - 1, 2)     # rows of the given trajectory (the hanging pose prepended)
        case = (t[:k], p[:k], q[:k], start)
    sets = dict(kv.split('=', 1) for kv in args.set)
    cpu = time.process_time()
    run = run_elastica if args.sim == 'elastica' else run_der
    times, nodes, deployed, t_rel, desc, extra = run(case, rod, friction_coefficient(args.friction, FRICTION_LEVELS),
                                                     sets, args.every)
    cpu = time.process_time() - cpu
    # a lead-in-only replay may lay less than two nodes: no Eq. 17 then
    e = eq17_error(P, deployed) if len(deployed) >= 2 else {'e_mean_cm': float('nan')}
    np.savez(args.out, times=times, nodes=nodes, pattern=P, deployed=deployed, e_mean_cm=e['e_mean_cm'],
             t_release_s=t_rel, cpu_s=cpu, settings=desc, **extra)
    print(f"{args.sim} {args.pattern} {args.method} {sets}: e_mean {e['e_mean_cm']:.3f} cm, free end moved "
          f"{1e3 * np.linalg.norm(deployed[0] - P[0, :2]):.1f} mm, release at {t_rel:.1f} s, CPU {cpu:.0f} s")


if __name__ == '__main__':
    main()
