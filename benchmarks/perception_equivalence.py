"""Do two versions of the perception give the same outputs? For speed work that must not change any result.

    .venv/bin/python benchmarks/perception_equivalence.py --save out/perception_before.pkl      # old checkout
    .venv/bin/python benchmarks/perception_equivalence.py --compare out/perception_before.pkl   # new checkout
                                                          [--tolerance-px 1e-12] [--no-crossing-scenes]

Runs :func:`rod_deploy.perception.pipeline.perceive` on the published mBEST photos (``--data``, read in place),
the drawn patterns and the random rod scenes of ``perception_mbest.py`` (development and held-out seeds: the
outputs are only compared, nothing is tuned on them), and the crossing scenes of ``perception_crossings.py``
that are in its cache (``--set dev`` of that script; ``--generate-only`` fills the cache), and keeps per image
the ordered centrelines, widths, closed flags and crossing decisions (or the error message). ``--compare``
reports every image whose outputs differ: another number of objects or crossings, another closed flag, over/under
object, cue or error, or a point, width, position, confidence or separation more than ``--tolerance-px`` (default
0: bit for bit) apart. Exit status 1 if any differ.
"""
from __future__ import annotations

import argparse
import glob
import pickle
import sys
from pathlib import Path

import cv2
import numpy as np

from perception_crossings import CACHE
from perception_mbest import draw_strokes, drawn_cases, random_rod_scenes
from rod_deploy.perception import pipeline
from rod_deploy.perception.pipeline import PerceptionError, perceive

ROOT = Path(__file__).resolve().parent.parent


def cases(data: Path, shared: Path, crossing_scenes: bool):
    """(name, image) of every image compared, generated lazily."""
    for f in sorted(glob.glob(str(data / 'mBEST' / '*.jpg'))):
        yield f'mBEST {Path(f).stem}', cv2.imread(f)
    for name, curve, size in drawn_cases(shared):
        for width in (3.0, 6.0, 12.0):
            yield f'drawn {name} {width:g}', draw_strokes(
                (size, size), [curve], [width], [(40, 30, 30)], background=(235, 235, 228), noise_std=3.0,
                gradient=0.25, blur_sigma=0.8, seed=int(width))
    for seed, n in ((7, 30), (4242, 60)):            # perception_mbest.bench_random_scenes' draws
        for trial, image, *_ in random_rod_scenes(n, seed):
            yield f'rod scene {seed} {trial}', image
    if crossing_scenes:
        for f in sorted(CACHE.glob('*.npz')):
            yield f'crossing scene {f.stem}', np.load(f, allow_pickle=True)['scene'].item().image


def outputs(image):
    """What perceive returns that a user sees: objects and crossing decisions, or the error message."""
    try:
        res = perceive(image)
    except PerceptionError as exc:
        return {'error': str(exc)}
    return {'objects': [(o.points, o.width_px, o.closed) for o in res.objects],
            'crossings': [(d.crossing, d.position, d.objects, d.over, d.confidence, d.separation, d.cue)
                          for d in res.crossings]}


def differences(a, b, tol):
    """Why outputs ``a`` and ``b`` differ (empty list: the same within ``tol``)."""
    if 'error' in a or 'error' in b:
        return [] if a.get('error') == b.get('error') else [f"error {a.get('error')!r} vs {b.get('error')!r}"]
    out = []
    if len(a['objects']) != len(b['objects']):
        return [f"{len(a['objects'])} vs {len(b['objects'])} objects"]
    for k, ((pa, wa, ca), (pb, wb, cb)) in enumerate(zip(a['objects'], b['objects'])):
        if ca != cb or pa.shape != pb.shape:
            out.append(f'object {k}: closed {ca} vs {cb}, {len(pa)} vs {len(pb)} points')
        elif np.abs(pa - pb).max(initial=0.0) > tol or abs(wa - wb) > tol:
            out.append(f'object {k}: points up to {np.abs(pa - pb).max():.3g} px apart, widths {wa} vs {wb}')
    if len(a['crossings']) != len(b['crossings']):
        return out + [f"{len(a['crossings'])} vs {len(b['crossings'])} crossings"]
    for k, (da, db) in enumerate(zip(a['crossings'], b['crossings'])):
        same_discrete = da[0] == db[0] and da[2] == db[2] and da[3] == db[3] and da[6] == db[6]
        close = all(np.abs(np.asarray(x, float) - np.asarray(y, float)).max() <= tol
                    for x, y in ((da[1], db[1]), (da[4], db[4]), (da[5], db[5])))
        if not (same_discrete and close):
            out.append(f'crossing {k}: {da} vs {db}')
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument('--save', type=Path, help='write this checkout\'s outputs here')
    mode.add_argument('--compare', type=Path, help='compare this checkout\'s outputs with a saved run')
    p.add_argument('--data', type=Path, default=ROOT.parent / 'shared' / 'data' / 'dlo_images')
    p.add_argument('--shared', type=Path, default=ROOT.parent / 'shared')
    p.add_argument('--tolerance-px', type=float, default=0.0)
    p.add_argument('--no-crossing-scenes', action='store_true')
    args = p.parse_args()
    results = {name: outputs(img) for name, img in cases(args.data, args.shared, not args.no_crossing_scenes)}
    if args.save:
        args.save.parent.mkdir(parents=True, exist_ok=True)
        with open(args.save, 'wb') as f:
            pickle.dump(results, f)
        print(f'{len(results)} images perceived by {Path(pipeline.__file__).parent}, outputs saved in {args.save}')
        return
    with open(args.compare, 'rb') as f:
        saved = pickle.load(f)
    common = [name for name in results if name in saved]
    differing = 0
    for name in common:
        why = differences(saved[name], results[name], args.tolerance_px)
        if why:
            differing += 1
            print(f'{name}: ' + '; '.join(why))
    missing = len(saved) - len(common)
    print(f'{Path(pipeline.__file__).parent}: {len(common)} images compared ({missing} saved ones not run here, {len(results) - len(common)} new): '
          f'{differing} differ (tolerance {args.tolerance_px:g} px)')
    sys.exit(1 if differing or not common else 0)


if __name__ == '__main__':
    main()
