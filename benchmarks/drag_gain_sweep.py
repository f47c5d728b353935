"""The drag compensation's gains against the table friction (issue #10): the planner's default plan with the gains
of ``bend_drag.drag_offsets`` replaced by each of a few values, deployed in our DER, per development pattern.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/drag_gain_sweep.py --friction 0.2 \
        --gains 0.3,0.75,1.2,2.0 [--patterns letterL,sine,letterU,letterA,letterC,circle] [--rods 3] \
        [--out-name NAME.md] [--commit-results]

A gain is the drag term's alone (the shift term's 0) or ``DRAG/SHIFT`` (the two terms of ``bend_drag.drag_terms``),
e.g. ``0.3/0.42``.

Development patterns only (the paper's 7 and the deployment table's own shapes; never a held-out seed). Eq. 17
e_mean [cm] (N = 50) with the defaults of ``rod-deploy simulate`` at the given friction, the planner told it; per
gain the template's largest offset from the pattern [mm]. ``--gains default`` adds the planner's own gain.
"""
from __future__ import annotations

import argparse
import functools
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402


def parse_gain(text):
    """'0.3' -> the drag term's gain alone; 'DRAG/SHIFT' -> the two gains."""
    g = [float(v) for v in text.split('/')]
    if len(g) == 1:
        g.append(0.0)
    if len(g) != 2:
        raise ValueError(f'a gain is one number or DRAG/SHIFT, got {text!r}')
    return {'gains': tuple(g)}


def main():
    import rod_deploy.planning.bend_drag as bend_drag
    from deployment_table import RODS, all_patterns
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.deployment.simulate import SimulationSettings, simulate_deployment
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory

    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--patterns', default='letterL,sine,letterU,letterA,letterC,circle')
    ap.add_argument('--rods', default='3')
    ap.add_argument('--friction', type=float, default=0.2)
    ap.add_argument('--gains', default='default,0.75,1.2,2.0', help="comma-separated; 'default': the planner's")
    ap.add_argument('--out-name', default=None)
    add_results_argument(ap)
    args = ap.parse_args()
    rod_ids = [int(r) for r in args.rods.split(',')]
    mu = args.friction
    out = results_path(args, args.out_name or f'drag_gain_sweep_rod{args.rods.replace(",", "")}_mu{mu:g}.md')
    own = bend_drag.drag_offsets
    gains = args.gains.split(',')
    names = args.patterns.split(',')
    keys = [(r, n) for r in rod_ids for n in names]
    e = {}
    t_all, cpu_all = time.perf_counter(), time.process_time()
    for gain in gains:
        bend_drag.drag_offsets = own if gain == 'default' else functools.partial(own, **parse_gain(gain))
        for rod_id in rod_ids:
            rod = rod_description_from_dict(RODS[rod_id])
            for name in names:
                P = all_patterns(name)[name]
                plan = plan_trajectory(P, rod, PlannerSettings(friction=mu))
                res = simulate_deployment(plan.t, plan.position, plan.quaternion, rod, SimulationSettings(friction=mu))
                e[gain, (rod_id, name)] = (eq17_error(P, res.deployed_xy)['e_mean_cm'], 1e3 * plan.drag_offset_max())
                print(gain, rod_id, name, e[gain, (rod_id, name)], flush=True)
    bend_drag.drag_offsets = own
    label = {g: (f'default ({bend_drag.DRAG_GAIN:g})' if g == 'default' else g) for g in gains}
    lines = [f'# Drag gain sweep, `python benchmarks/drag_gain_sweep.py --friction {mu:g}` (rods {args.rods})', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{os.getloadavg()[0]:.1f} at writing); {time.perf_counter() - t_all:.0f} s, CPU '
             f'{time.process_time() - cpu_all:.0f} s. Our DER (defaults of `rod-deploy simulate`, friction {mu:g}), '
             'planner nn with its defaults but the drag gain [L_gb per unit excess]; Eq. 17 e_mean in cm (the '
             'template\'s largest offset in mm).', '',
             '| rod | pattern | ' + ' | '.join(f'gain {label[g]}' for g in gains) + ' |',
             '|---|---|' + '---|' * len(gains)]
    for k in keys:
        lines.append(f'| #{k[0]} | {k[1]} | ' + ' | '.join(f'{e[g, k][0]:.3f} ({e[g, k][1]:.1f})' for g in gains)
                     + ' |')
    lines.append('| | mean | ' + ' | '.join(f'{np.mean([e[g, k][0] for k in keys]):.3f}' for g in gains) + ' |')
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


if __name__ == '__main__':
    main()
