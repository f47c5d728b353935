"""How much of the friction excess at the touch-down point falls within the friction-limited start's stretch
(issue #10): the stretch the start replaces (``trajectory._replaced_stretch``: up to the last node it moved by more
than 0.1 mm) and the excess |D| - mu F_z of the uncompensated plan inside it and after it (planning only).

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/drag_start_stretch.py [--commit-results]

Development patterns only (the paper's 7 and the deployment table's own shapes), rod #3. The planner's drag
compensation is zero over that stretch (``drag_offsets(start_m=...)``; the tag experiment/drag-in-start compensates
it too).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402

CASES = [(0.2, 'letterA,letterC,letterL,letterU,sine,circle,line'),
         (0.5, 'letterA,letterC,letterL,letterU,sine,circle,line,spiral,digit2,letterS,loop_crossing,digit6,letterG,'
               'wave_tight'),
         (1.0, 'letterA,letterC,letterL,letterU,sine,circle,line')]


def main():
    from deployment_table import RODS, all_patterns
    from rod_deploy.planning.bend_drag import friction_excess
    from rod_deploy.planning.rod_description import rod_description_from_dict
    from rod_deploy.planning.trajectory import PlannerSettings, _replaced_stretch, plan_trajectory
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    add_results_argument(ap)
    args = ap.parse_args()
    rod = rod_description_from_dict(RODS[3])
    lgb = rod.gravito_bending_length_m
    lines = ['# The friction excess within the friction-limited start, `python benchmarks/drag_start_stretch.py`', '',
             'Rod #3, the planner\'s uncompensated plan (`drag_compensation=False`); excess |D| - mu F_z of the planned '
             'curvature [k_b / L_gb^2]: largest, and its integral over s / L_gb, inside the replaced start and after '
             'it.', '', '| friction | pattern | pattern cm | replaced start cm | max excess inside | integral inside | '
             'max excess after | integral after |', '|---|---|---|---|---|---|---|---|']
    for mu, names in CASES:
        for name in names.split(','):
            P = all_patterns(name)[name]
            p = plan_trajectory(P, rod, PlannerSettings(friction=mu, drag_compensation=False))
            g = p.drawn_pattern
            _, length = _replaced_stretch(g, p.start_pattern)
            kb = np.interp(g.s, p.pattern.s, p.inputs[:, 2])
            ex = np.abs(friction_excess(g.s / lgb, kb, mu)[0])
            inside = g.s < length

            def part(k):
                if k.sum() < 2:
                    return 0.0, 0.0
                return float(ex[k].max()), float(np.trapezoid(ex[k], g.s[k] / lgb))
            a, b = part(inside), part(~inside)
            lines.append(f'| {mu:g} | {name} | {100 * g.length:.0f} | {100 * length:.1f} | {a[0]:.2f} | {a[1]:.2f} | '
                         f'{b[0]:.2f} | {b[1]:.2f} |')
    out = results_path(args, 'drag_start_stretch.md')
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
