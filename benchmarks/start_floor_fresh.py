"""What limits the fresh rehearsal's worst shapes (issue #10): the floor of the planned curve under the planner's
constraints, and with each constraint loosened, against the planner's own planned curve.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/start_floor_fresh.py \
        [--shapes cursive_a,digit9,long_meander_0p855m]

For each shape of the fresh rehearsal set (on its rod, friction 0.5; the processed pattern the planner plans on,
drag compensation off): Eq. 17 e_mean (N = 50, against the processed pattern) of the curve the planner's grasps ask
for (``_planned_curve`` with ``looser_start`` off, friction_share 1), then ``start_floor.closest_bounded_curve``
(SLSQP, the free end at the pattern's first point, heading free) under the planner's constraints - the friction
bound c mu s^2 / (8 L_gb^3) with c = 1, capped at 0.9 x 4 / L_gb, and the curvature rate limit 0.35 per L_gb - from
five starts (``start_floor.starts``' four and the planner's own curvature), then with one constraint changed at a
time: no rate limit; c = 1.5, 2 (the static bound every rod at rest obeys) and 4; the rate limit doubled. Printed,
one line per shape; a local optimum each (an upper bound on the floor).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import acceptance_rehearsal as ar  # noqa: E402
from start_floor import closest_bounded_curve, starts  # noqa: E402


def main():
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.planning.achievable_start import friction_curvature_limit
    from rod_deploy.planning.curvature_rate import default_max_rate
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, _planned_curve, process_pattern

    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--shapes', default='cursive_a,digit9,long_meander_0p855m')
    args = ap.parse_args()
    shp = ar.fresh_shapes()
    mu = 0.5
    rate = default_max_rate(mu)
    for name in args.shapes.split(','):
        rd = ar.RODS[ar.FRESH_RODS[name][0]]
        rod = rod_description_from_dict({'length': rd['length'], 'radius': rd['radius'], 'L_gb': rd['L_gb'],
                                         'friction': mu})
        lgb = rod.gravito_bending_length_m
        st = PlannerSettings(drag_compensation=False, looser_start=False)
        given = process_pattern(shp[name][0], st.step_m, st.smoothing_m, st.end_weight)
        _, inputs, asked, _ = _planned_curve(given, rod, st, mu)
        line = [f'{name}: planner {eq17_error(given.xy, asked)["e_mean_cm"]:.3f}']

        def floor(c, rate_bar, init=None):
            kmax = np.minimum(friction_curvature_limit(given.s, lgb, mu, c), 0.9 * st.max_abs_kappa_bar / lgb)
            xy, _ = closest_bounded_curve(given, kmax, False, rate_bar=rate_bar, lgb=lgb, kappa_init=init)
            return eq17_error(given.xy, xy)['e_mean_cm']
        kmax1 = np.minimum(friction_curvature_limit(given.s, lgb, mu), 0.9 * st.max_abs_kappa_bar / lgb)
        inits = list(starts(given.kappa, kmax1, 4)) + [-inputs[:, 2] / lgb]
        line.append('planner\'s constraints from 5 starts ' + ', '.join(f'{floor(1.0, rate, k):.3f}' for k in inits))
        line.append(f'no rate limit {floor(1.0, None):.3f}')
        for c in (1.5, 2.0, 4.0):
            line.append(f'c {c:g} {floor(c, rate):.3f}')
        line.append(f'rate x2 {floor(1.0, 2 * rate):.3f}')
        print('; '.join(line), flush=True)


if __name__ == '__main__':
    main()
