"""Where `perceive` spends its CPU time on the published mBEST photos: per pipeline step, process CPU time.

    .venv/bin/python benchmarks/perception_profile.py [--data ../shared/data/dlo_images] [--repeats 20]
                                                      [--commit-results]

Each step that :func:`rod_deploy.perception.pipeline.perceive` calls (and the centreline refinement's
``refine`` and ``place_ends``) is timed by process CPU time (``time.process_time``: all threads; other
processes inflate it less than the wall clock on a loaded machine) over ``--repeats`` runs of every photo (image
in memory, kernels compiled); the table gives the mean CPU ms per image of each step (summed over its calls in
one run), its share of the whole run's mean, and the median CPU ms of a whole run per image. Steps can nest
(``distance_map`` and ``_median_evidence`` also run inside other steps, through the pipeline's callbacks), so the
shares can add up to more than 100 %. The timers add about 1 us per call. The outputs are not touched (the same functions, only wrapped while this script runs).
"""
from __future__ import annotations

import argparse
import functools
import glob
import os
import time
from pathlib import Path

import cv2
import numpy as np

import rod_deploy.perception.centreline as cl
import rod_deploy.perception.pipeline as pipeline
from results_dir import add_results_argument, results_path

ROOT = Path(__file__).resolve().parent.parent
STEPS = ('segment', 'skeleton_mask', 'skeleton_of', 'build_skeleton_graph', 'distance_map', '_centreline_width',
         'remove_small_parts', 'prune_spurs', 'prune_blob_spurs', 'dissolve_pass_through_junctions',
         'find_crossings', 'pair_crossings', 'trace_objects', 'split_at_colour_changes', 'join_gaps',
         '_crossing_zones', '_median_evidence', 'drop_shadow_strands', 'decide_crossings', 'trace_filled_loop',
         'separate_side_by_side', '_place_abutting_ends', '_canonical_order', '_in_zones')
CENTRELINE_STEPS = ('refine', 'place_ends')


def timed(module, name, key, totals):
    original = getattr(module, name)

    @functools.wraps(original)
    def wrapper(*args, **kwargs):
        c0 = time.process_time()
        try:
            return original(*args, **kwargs)
        finally:
            totals[key] = totals.get(key, 0.0) + time.process_time() - c0
    setattr(module, name, wrapper)
    return original


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--data', default=str(ROOT.parent / 'shared' / 'data' / 'dlo_images'))
    parser.add_argument('--repeats', type=int, default=20)
    add_results_argument(parser)
    args = parser.parse_args()
    files = sorted(glob.glob(str(Path(args.data) / 'mBEST' / '*.jpg')))
    if not files:
        raise SystemExit(f'no mBEST photos in {Path(args.data) / "mBEST"}')
    images = [cv2.imread(f) for f in files]
    totals: dict[str, float] = {}
    originals = [(pipeline, n, timed(pipeline, n, n, totals)) for n in STEPS]
    originals += [(cl, n, timed(cl, n, f'centreline.{n}', totals)) for n in CENTRELINE_STEPS]
    try:
        for img in images:
            pipeline.perceive(img)                      # compiled kernels loaded, caches warm
        totals.clear()
        load_start = os.getloadavg()
        runs = []
        for _ in range(args.repeats):
            for img in images:
                c0 = time.process_time()
                pipeline.perceive(img)
                runs.append((time.process_time() - c0) * 1e3)
        load_end = os.getloadavg()
    finally:
        for module, name, original in originals:
            setattr(module, name, original)
    n = len(runs)
    whole = float(np.mean(runs))
    lines = ['# Perception CPU time per step (`benchmarks/perception_profile.py`)', '',
             f'{len(images)} mBEST photos x {args.repeats} repeats; load average at the start '
             f'{", ".join(f"{v:.1f}" for v in load_start)}, at the end {", ".join(f"{v:.1f}" for v in load_end)} '
             f'({os.cpu_count()} logical CPUs). Process CPU time (all threads); steps can nest (see the script). '
             f'Whole run per image: median '
             f'{np.median(runs):.2f} ms, mean {whole:.2f} ms.', '',
             '| step | CPU ms per image (mean) | share |', '|---|---|---|']
    for key, total in sorted(totals.items(), key=lambda kv: -kv[1]):
        lines.append(f'| {key} | {total / n * 1e3:.3f} | {100 * total / n * 1e3 / whole:.0f} % |')
    text = '\n'.join(lines) + '\n'
    out = results_path(args, 'perception_profile.md')
    out.write_text(text)
    print(text)


if __name__ == '__main__':
    main()
