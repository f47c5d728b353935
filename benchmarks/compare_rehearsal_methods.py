"""Shape by shape comparison of two methods of one acceptance-rehearsal results file (``acceptance_rehearsal.py``'s
json): Eq. 17 e_mean and the CPU time of ``rod-deploy plan`` and ``rod-deploy simulate`` (each process's own, from
wait4), on the shapes both methods simulated.

    python benchmarks/compare_rehearsal_methods.py --results acceptance_rehearsal_fresh_least_force.json \
        --before numeric --after 'numeric --shear least_force' --out NAME.md [--commit-results]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from results_dir import COMMITTED, add_results_argument, results_path


def runs_by_shape(runs, method):
    """{shape: run} of the runs of ``method`` (the label acceptance_rehearsal.py gives: method and extra arguments)."""
    return {r['shape']: r for r in runs if r['method'] == method}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--results', required=True, help='the json (a name in benchmarks/results/, or a path)')
    ap.add_argument('--before', required=True)
    ap.add_argument('--after', required=True)
    ap.add_argument('--out', required=True)
    ap.add_argument('--threshold', type=float, default=0.005, help='cm: a change counted as better / worse')
    add_results_argument(ap)
    args = ap.parse_args()
    src = Path(args.results) if Path(args.results).exists() else COMMITTED / args.results
    data = json.loads(src.read_text())
    before, after = runs_by_shape(data['runs'], args.before), runs_by_shape(data['runs'], args.after)
    if not before or not after:
        raise SystemExit(f'{src}: no runs of {args.before!r} or of {args.after!r} (methods there: '
                         f'{sorted({r["method"] for r in data["runs"]})})')
    lines = [f'# `{args.before}` vs `{args.after}` on the runs of `{src.name}`', '',
             f'Written by `benchmarks/compare_rehearsal_methods.py` from `{src.name}` (load average at the end of the '
             f'runs: {"-" if data.get("load_end") is None else format(data["load_end"], ".1f")}). Eq. 17 e_mean in cm (N = 50); CPU: each `rod-deploy` process\'s '
             'own CPU time (wait4) in s; "-": not simulated (refused, or failed: see the results file).', '',
             f'| shape | rod (form) | e_mean before | e_mean after | change | plan CPU before | plan CPU after | '
             'simulate CPU before | simulate CPU after |', '|---|---|---|---|---|---|---|---|---|']
    pairs, plan_c, sim_c = [], {'b': [], 'a': []}, {'b': [], 'a': []}

    def e(r):
        return (r.get('eval') or {}).get('e_mean_cm')

    def f(v, fmt='.3f'):
        return '-' if v is None else format(v, fmt)

    for shape in [s for s in before if s in after]:
        b, a = before[shape], after[shape]
        eb, ea = e(b), e(a)
        if eb is not None and ea is not None:        # the CPU medians: of the shapes both simulated
            pairs.append((eb, ea))
            for k, r in (('b', b), ('a', a)):
                plan_c[k].append(r['plan_cpu'])
                sim_c[k].append(r['sim_cpu'])
        lines.append(f'| {shape} | {b["rod"]} ({b["form"]}) | {f(eb)} | {f(ea)} | '
                     f'{"-" if eb is None or ea is None else format(ea - eb, "+.3f")} | {f(b.get("plan_cpu"), ".1f")} '
                     f'| {f(a.get("plan_cpu"), ".1f")} | {f(b.get("sim_cpu"), ".1f")} | {f(a.get("sim_cpu"), ".1f")} |')
    if pairs:
        p = np.array(pairs)
        d = p[:, 1] - p[:, 0]
        lines += ['', f'Shapes simulated by both: {len(p)}; mean e_mean {p[:, 0].mean():.3f} -> {p[:, 1].mean():.3f} '
                      f'cm (median {np.median(p[:, 0]):.3f} -> {np.median(p[:, 1]):.3f}); better by more than '
                      f'{args.threshold:g} cm: {int((d < -args.threshold).sum())}, worse: '
                      f'{int((d > args.threshold).sum())}, within: {int((abs(d) <= args.threshold).sum())}. '
                      f'Median CPU of plan {np.median(plan_c["b"]):.1f} -> {np.median(plan_c["a"]):.1f} s, of simulate '
                      f'{np.median(sim_c["b"]):.1f} -> {np.median(sim_c["a"]):.1f} s.']
    out = results_path(args, args.out)
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))
    print(f'results: {out}')


if __name__ == '__main__':
    main()
