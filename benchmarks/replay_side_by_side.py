"""Our DER and PyElastica side by side on the paper's 7 patterns, from ``pyelastica_replay.py`` result files (each row
holds PyElastica's e_mean and our DER's on the same trajectory, ``ours_e_mean_cm``), with issue #10's targets:
e_mean <= 0.1 cm in our DER and <= 0.2 cm in PyElastica (medium friction), our planner better than the intuitive
baseline on every pattern and >= 3x on average.

    python benchmarks/replay_side_by_side.py --runs LABEL=FILE.json ... [--ours-label nn] [--baseline intuitive] \
        [--out-name NAME.md] [--note TEXT] [--commit-results]

LABEL names a column group (e.g. ``rod3 nn``); a file holding several planners needs ``LABEL=FILE.json@PLANNER``.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402

PATTERNS = ('line', 'circle', 'sine', 'letterU', 'letterC', 'letterL', 'letterA')


def read_runs(specs):
    """{label: {pattern: (PyElastica e_mean, DER e_mean, file name)}}"""
    out = {}
    for spec in specs:
        label, _, f = spec.partition('=')
        f, _, planner = f.partition('@')
        if not f:
            raise SystemExit(f'replay_side_by_side: error: --runs takes LABEL=FILE.json[@PLANNER], got {spec!r}')
        rows = json.loads(Path(f).read_text())['rows']
        planners = {r['planner'] for r in rows}
        if not planner and len(planners) > 1:
            raise SystemExit(f'replay_side_by_side: error: {f} holds the planners {sorted(planners)}: name one '
                             '(LABEL=FILE.json@PLANNER)')
        for r in rows:
            if r['pattern'] not in PATTERNS or (planner and r['planner'] != planner):
                continue
            if r['pattern'] in out.get(label, {}):
                raise SystemExit(f'replay_side_by_side: error: {label}: {r["pattern"]} twice')
            out.setdefault(label, {})[r['pattern']] = (r['e_mean_cm'], r.get('ours_e_mean_cm', float('nan')),
                                                       Path(f).name)
    return out


def _c(v, fmt='.3f'):
    return '-' if v is None or not np.isfinite(v) else format(v, fmt)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--runs', nargs='+', required=True, metavar='LABEL=FILE.json')
    ap.add_argument('--ours-label', default=None, help='the label of our planner for the ratios')
    ap.add_argument('--baselines', default='', help='comma-separated labels to compare ours with (ratio baseline/ours)')
    ap.add_argument('--out-name', default='replay_side_by_side.md')
    ap.add_argument('--note', default='')
    add_results_argument(ap)
    args = ap.parse_args()
    runs = read_runs(args.runs)
    labels = list(runs)
    lines = ['# Our DER and PyElastica side by side, the 7 published patterns, `benchmarks/replay_side_by_side.py`', '',
             'e_mean cm (Eq. 17, N = 50) of the same trajectory in our DER ("DER") and replayed in PyElastica 1.0.0 '
             '("PyEl."); medium friction (mu 0.5). Targets (issue #10): DER <= 0.1, PyElastica <= 0.2. Files: '
             + ', '.join(f'{lab}: `{next(iter(runs[lab].values()))[2]}`' for lab in labels) + '.', '']
    if args.note:
        lines += [args.note, '']
    head = '| pattern | ' + ' | '.join(f'{lab} DER | {lab} PyEl. | {lab} diff' for lab in labels) + ' |'
    lines += [head, '|---|' + '---|' * (3 * len(labels))]
    for p in PATTERNS:
        cells = []
        for lab in labels:
            el, der, _ = runs[lab].get(p, (float('nan'), float('nan'), ''))
            flag_d = '' if not np.isfinite(der) or der <= 0.1 else ' (>0.1)'
            flag_e = '' if not np.isfinite(el) or el <= 0.2 else ' (>0.2)'
            cells += [_c(der) + flag_d, _c(el) + flag_e, _c(el - der, '+.3f')]
        lines.append(f'| {p} | ' + ' | '.join(cells) + ' |')
    cells = []
    for lab in labels:
        el = np.array([runs[lab].get(p, (np.nan, np.nan, ''))[0] for p in PATTERNS])
        der = np.array([runs[lab].get(p, (np.nan, np.nan, ''))[1] for p in PATTERNS])
        cells += [_c(np.nanmean(der)), _c(np.nanmean(el)), _c(np.nanmean(el - der), '+.3f')]
    lines.append('| **mean** | ' + ' | '.join(cells) + ' |')
    if args.ours_label and args.baselines:
        ours = runs[args.ours_label]
        lines += ['', f'Ratios baseline / ours ({args.ours_label}), per pattern; "mean ratio" is the mean of the '
                      'per-pattern ratios, "ratio of means" the baseline\'s mean e_mean over ours.', '',
                  '| baseline | simulator | ' + ' | '.join(PATTERNS) + ' | mean ratio | ratio of means | '
                  'ours better on every pattern |', '|---|---|' + '---|' * (len(PATTERNS) + 3)]
        for base in args.baselines.split(','):
            for k, sim in ((1, 'DER'), (0, 'PyElastica')):
                r = [runs[base][p][k] / ours[p][k] if p in runs[base] and p in ours else math.nan for p in PATTERNS]
                mb = np.nanmean([runs[base][p][k] for p in PATTERNS if p in runs[base] and p in ours])
                mo = np.nanmean([ours[p][k] for p in PATTERNS if p in runs[base] and p in ours])
                lines.append(f'| {base} | {sim} | ' + ' | '.join(_c(v, '.1f') for v in r) +
                             f' | {_c(np.nanmean(r), ".1f")} | {_c(mb / mo, ".1f")} | '
                             f'{"yes" if all(v > 1 for v in r if np.isfinite(v)) else "no"} |')
    out = results_path(args, args.out_name)
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))
    print(f'results: {out}')


if __name__ == '__main__':
    main()
