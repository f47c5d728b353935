"""Row by row comparison of deployment tables (``deployment_table.py`` outputs): e_mean of each (rod, friction,
pattern, planner) row in a "before" and an "after" set of tables.

    python benchmarks/compare_deployment_tables.py --before A.md,B.md --after C.md,D.md --out NAME.md \
        [--title TEXT] [--threshold 0.005] [--commit-results]
"""
from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np

from results_dir import add_results_argument, results_path

ROW = re.compile(r'^\| (#\d) \| (\w+) \| (\w+) \| (\w+) \| ([0-9.]+) \|')


def read_rows(paths):
    """{(rod, friction, pattern, planner): e_mean cm} of the tables' rows."""
    rows = {}
    for p in paths:
        for line in Path(p).read_text().splitlines():
            m = ROW.match(line)
            if m:
                rows[m.groups()[:4]] = float(m.group(5))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--before', required=True)
    ap.add_argument('--after', required=True)
    ap.add_argument('--out', required=True)
    ap.add_argument('--title', default='Deployment tables: before and after')
    ap.add_argument('--threshold', type=float, default=0.005, help='cm: a change counted as better / worse')
    add_results_argument(ap)
    args = ap.parse_args()
    before, after = read_rows(args.before.split(',')), read_rows(args.after.split(','))
    keys = [k for k in after if k in before]
    if not keys:
        raise SystemExit('no row in both sets of tables')
    lines = [f'# {args.title}', '', f'before: {args.before}; after: {args.after} (Eq. 17 e_mean, cm).', '',
             '| rod | friction | pattern | planner | before | after | change |', '|---|---|---|---|---|---|---|']
    for k in keys:
        lines.append(f'| {" | ".join(k)} | {before[k]:.3f} | {after[k]:.3f} | {after[k] - before[k]:+.3f} |')
    lines += ['', '| rows | cases | mean before | mean after | max before | max after | better / worse (> '
              f'{args.threshold:g} cm) |', '|---|---|---|---|---|---|---|']
    groups = {}
    for k in keys:
        groups.setdefault(f'{k[0]} {k[1]}', []).append(k)
    groups['all'] = keys
    for g, ks in groups.items():
        b, a = np.array([before[k] for k in ks]), np.array([after[k] for k in ks])
        lines.append(f'| {g} | {len(ks)} | {b.mean():.3f} | {a.mean():.3f} | {b.max():.3f} | {a.max():.3f} | '
                     f'{int(np.sum(a < b - args.threshold))} / {int(np.sum(a > b + args.threshold))} |')
    out = results_path(args, args.out)
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
