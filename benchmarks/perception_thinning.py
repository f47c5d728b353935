"""Thinning for the perception skeleton: the pipeline's compiled Zhang-Suen with Lü and Wang's bound and Holt
et al.'s staircase removal (``rod_deploy.perception.thinning``), scikit-image's ``skeletonize`` (which the
pipeline used before; its table has no published rule, so the skeletons differ by a few pixels) and OpenCV
contrib's ``cv2.ximgproc.thinning`` (Zhang-Suen and Guo-Hall), on the segmentation masks at full resolution
and on the masks the pipeline thins (half resolution for strokes 9 px wide or more: "(half)").

    python benchmarks/perception_thinning.py [--data ../shared/data/dlo_images] [--repeats 20] [--commit-results]

The contrib build is not a dependency of the project (``opencv-python-headless`` is); to measure it, put a
``opencv-contrib-python-headless`` of the same version first on the path, e.g.
``pip install --no-deps --target /tmp/cvcontrib opencv-contrib-python-headless==<version>`` and
``PYTHONPATH=/tmp/cvcontrib:...``. Without it only scikit-image is timed.
Per mask (the published mBEST photos, and crossing scenes of each kind): skeleton pixels, pixels that
differ from scikit-image's skeleton, and the median time (wall clock, and CPU time for ours and scikit-image's)
of each thinning of the mask's bounding box (as ``skeleton_of`` crops it) over ``--repeats`` runs.
"""
from __future__ import annotations

import argparse
import glob
import os
import time
from pathlib import Path

import cv2
import numpy as np
from skimage.morphology import skeletonize

from results_dir import add_results_argument, results_path
from rod_deploy.perception.crossing_scenes import SCENE_KINDS, crossing_scene
from rod_deploy.perception.pipeline import skeleton_mask
from rod_deploy.perception.segmentation import segment
from rod_deploy.perception.thinning import zhang_suen_thinning

ROOT = Path(__file__).resolve().parent.parent


def crop(mask):
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    return np.ascontiguousarray(mask[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1])


def timed(fn, repeats, cpu=False):
    out = fn()
    times, cpu_times = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
        cpu_times.append((time.process_time() - c0) * 1e3)
    return (out, float(np.median(times))) + ((float(np.median(cpu_times)),) if cpu else ())


def measure(name, mask, repeats, contrib):
    m = crop(mask)
    m8 = m.astype(np.uint8) * 255
    ref, t_sk, c_sk = timed(lambda: skeletonize(m), repeats, cpu=True)
    ours, t_ours, c_ours = timed(lambda: zhang_suen_thinning(m), repeats, cpu=True)
    row = dict(mask=name, pixels=int(m.sum()), skeleton=int(ref.sum()), ours_ms=t_ours, ours_cpu_ms=c_ours,
               ours_differ=int(np.count_nonzero(ours != ref)), skimage_ms=t_sk, skimage_cpu_ms=c_sk)
    if contrib:
        for label, kind in (('zhang_suen', cv2.ximgproc.THINNING_ZHANGSUEN),
                            ('guo_hall', cv2.ximgproc.THINNING_GUOHALL)):
            sk, t = timed(lambda: cv2.ximgproc.thinning(m8, thinningType=kind), repeats)
            sk = sk > 0
            row[f'{label}_ms'] = t
            row[f'{label}_differ'] = int(np.count_nonzero(sk != ref))
    return row


def main():
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--data', default=str(ROOT.parent / 'shared' / 'data' / 'dlo_images'))
    p.add_argument('--repeats', type=int, default=20)
    add_results_argument(p)
    args = p.parse_args()
    contrib = hasattr(cv2, 'ximgproc')
    rows = []
    images = [(Path(f).stem, cv2.imread(f)) for f in sorted(glob.glob(str(Path(args.data) / 'mBEST' / '*.jpg')))]
    images += [(f'scene {kind}', crossing_scene(kind, 1001).image) for kind in SCENE_KINDS]
    for name, image in images:
        seg = segment(image)
        rows.append(measure(name, seg.mask, args.repeats, contrib))
        print(rows[-1], flush=True)
        mask, f = skeleton_mask(seg)
        if f != 1:
            rows.append(measure(f'{name} (half)', mask, args.repeats, contrib))
            print(rows[-1], flush=True)
    load = os.getloadavg()
    cols = ['mask', 'pixels', 'skeleton', 'ours_ms', 'ours_cpu_ms', 'ours_differ', 'skimage_ms', 'skimage_cpu_ms'] + (
        ['zhang_suen_ms', 'zhang_suen_differ', 'guo_hall_ms', 'guo_hall_differ'] if contrib else [])
    lines = ['# Thinning: ours, scikit-image and OpenCV contrib (`benchmarks/perception_thinning.py`)', '',
             f'OpenCV {cv2.__version__} ({"with" if contrib else "without"} the contrib module ximgproc); '
             f'{os.cpu_count()} CPUs, load average at the end {", ".join(f"{v:.1f}" for v in load)}; median of '
             f'{args.repeats} runs on the cropped mask; "ours": the compiled Zhang-Suen the pipeline uses '
             "(`rod_deploy.perception.thinning`: Lü and Wang's bound, Holt et al.'s staircase removal); "
             '"differ": pixels where the skeleton differs from '
             "scikit-image's; \"(half)\": the half-resolution mask the pipeline thins for wide strokes.", '',
             '| ' + ' | '.join(cols) + ' |', '|' + '---|' * len(cols)]
    for r in rows:
        lines.append('| ' + ' | '.join(f'{r[c]:.2f}' if isinstance(r[c], float) else str(r[c]) for c in cols) + ' |')
    lines.append('')
    out = results_path(args, 'perception_thinning.md')
    out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
