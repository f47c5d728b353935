"""The deployed shape's end: the nodes within 0.3 mm of the table (the readout until the eleventh round) against the
same nodes ended at the touch-down point (``simulate.touchdown_cut``), scored with our Eq. 17 (``eq17_error``: a
deployed curve longer than the pattern compared over its first pattern length) and with an Eq. 17 that resamples
each curve over its own length (what a reader of the contract's "resample both curves by arc length" may compute).

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/readout_touchdown.py [--commit-results]

No simulation is run: the final nodes come from the PyElastica replays' results (``pyelastica_replay_r10_*.json``,
nodes stored to 1 um), the patterns from ``deployment_table.all_patterns`` (the paper's 7 read in place from
``../shared`` when present, and our own shapes).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from deployment_table import all_patterns  # noqa: E402
from results_dir import add_results_argument, results_path  # noqa: E402
from rod_deploy.deployment.metrics import eq17_error, resample  # noqa: E402
from rod_deploy.deployment.simulate import LAID_HEIGHT_TOLERANCE_M, deployed_shape  # noqa: E402

RESULTS = Path(__file__).resolve().parent / 'results'
RADIUS_M = {1: 0.0016, 2: 0.0016, 3: 0.002}


def tolerance_only(nodes, radius_m):
    """The readout before the eleventh round: the nodes up to the first one above the 0.3 mm tolerance."""
    on = nodes[:, 2] <= radius_m + LAID_HEIGHT_TOLERANCE_M
    return nodes[:int(np.argmin(on)) if not np.all(on) else len(nodes), :2]


def own_length_e_mean_cm(pattern, deployed):
    """Eq. 17 with each curve resampled over its own length (better direction), cm."""
    a = resample(np.asarray(pattern, float)[:, :2], 50)
    return min(100 * float(np.linalg.norm(a - resample(d, 50), axis=1).mean()) for d in (deployed, deployed[::-1]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    add_results_argument(ap)
    args = ap.parse_args()
    patterns = all_patterns()
    lines = ['# The deployed shape ended at the touch-down point (`benchmarks/readout_touchdown.py`)', '',
             __doc__.split('\n\n')[0].replace('\n', ' '), '',
             'e_mean in cm; "ours": `eq17_error`; "own length": both curves resampled over their own lengths; '
             'coverage: deployed length / pattern length. Old: the nodes within 0.3 mm of the table; new: ended at '
             'the touch-down point.', '',
             '| replay file | rod | pattern | planner | ours old -> new | own length old -> new | coverage old -> new |',
             '|---|---|---|---|---|---|---|']
    moved = []
    for f in sorted(RESULTS.glob('pyelastica_replay_r10_*.json')):
        for r in json.loads(f.read_text())['rows']:
            if r['pattern'] not in patterns or not r.get('nodes_mm'):
                continue
            rod = int(str(r['rod']).strip('#'))
            nodes = np.asarray(r['nodes_mm'], float) / 1000.0
            P = patterns[r['pattern']]
            old, new = tolerance_only(nodes, RADIUS_M[rod]), deployed_shape(nodes, RADIUS_M[rod])
            eo, en = eq17_error(P, old), eq17_error(P, new)
            oo, on = own_length_e_mean_cm(P, old), own_length_e_mean_cm(P, new)
            lines.append(f'| {f.stem} | #{rod} | {r["pattern"]} | {r["planner"]} | {eo["e_mean_cm"]:.4f} -> '
                         f'{en["e_mean_cm"]:.4f} | {oo:.4f} -> {on:.4f} | {eo["coverage"]:.3f} -> '
                         f'{en["coverage"]:.3f} |')
            if abs(en['e_mean_cm'] - eo['e_mean_cm']) >= 5e-4:
                moved.append(f'{f.stem} {r["pattern"]} {r["planner"]}')
    lines += ['', f'Rows whose e_mean (ours) moved by 0.0005 cm or more: {len(moved)}'
              + (': ' + '; '.join(moved) if moved else '') + '.']
    out = results_path(args, 'readout_touchdown.md')
    out.write_text('\n'.join(lines) + '\n')
    print(f'wrote {out}')


if __name__ == '__main__':
    main()
