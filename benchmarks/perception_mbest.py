"""Perception benchmark: the published mBEST photos, drawn patterns and random synthetic rod scenes.

    .venv/bin/python benchmarks/perception_mbest.py [--data ../shared/data/dlo_images] [--repeats 20]
                                                   [--out benchmarks/results/perception_mbest.md]

1. mBEST photos (read in place from ``<data>/mBEST``, skipped when absent): per image the number of
   objects found against the ground truth, the instance DICE (each perceived centreline drawn with its
   measured width, the upper object drawn last at decided crossings, matched one-to-one to the
   ground-truth instances; pooled over instances, and the mean per instance), and the median processing
   time over ``--repeats`` runs (image already in memory: segmentation to ordered paths). For reference the
   published mBEST paths are drawn the same way (their centreline and topology, our width estimate along
   them, no over/under order since the files do not carry it).
2. Drawn patterns: strokes of known centreline (test curves, the paper's seven patterns when
   ``../shared/reference/rod_deployment/patterns`` is present, random smooth curves) drawn at several widths
   on paper with shading and noise; centreline RMS [px] in both directions, end error, Eq. 17 mean.
3. Random rod scenes (1-3 rods of random colour, width and shape on dark or textured tables): how often
   the object count is right, and the DICE; the development set (seed 7) and a held-out set drawn the
   same way from another seed (4242), which no rule was tuned on.
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import platform
import time
from pathlib import Path

import cv2
import numpy as np

from results_dir import add_results_argument, results_path
from rod_deploy.perception import centreline as cl
from rod_deploy.perception.evaluation import arc_length_error, centreline_rms, instance_dice, render_instances
from rod_deploy.perception.pipeline import PerceivedObject, perceive
from rod_deploy.perception.synthetic import draw_strokes, example_curves, random_rod_curve, stroke_coverage

ROOT = Path(__file__).resolve().parent.parent


def width_along(points, seg):
    """Our width estimate (median edge-to-edge distance) along someone else's centreline."""
    pts = cl.resample(points.astype(float), 1.0)
    t = cl.tangents(cl.smooth(pts, 2.0, False), False)
    normals = np.stack([t[:, 1], -t[:, 0]], axis=1)
    prof, off = cl.edge_profiles(seg.evidence.astype(np.float32), pts, normals, 0.8 * seg.stroke_width_px + 3)
    lo, hi = cl.edge_positions(prof, off, 0.25 * seg.threshold, 0.5 * seg.stroke_width_px + 1)
    w = hi - lo
    return float(np.nanmedian(w)) if np.isfinite(w).any() else seg.stroke_width_px


def bench_mbest(data: Path, repeats: int):
    folder = data / 'mBEST'
    files = sorted(glob.glob(str(folder / '*.jpg')))
    rows = []
    for f in files:
        name = Path(f).stem
        img = cv2.imread(f)
        gt = cv2.imread(str(folder / f'{name}_gt_labels.png'), cv2.IMREAD_UNCHANGED)
        res = perceive(img)
        times, cpu = [], []
        for _ in range(repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            perceive(img)
            times.append((time.perf_counter() - t0) * 1e3)
            cpu.append((time.process_time() - c0) * 1e3)
        label = render_instances(res.objects, res.crossings, gt.shape)
        pooled, mean, _ = instance_dice(label, gt)
        row = dict(image=name, rods=int(gt.max()), found=len(res.objects), dice=pooled, dice_mean=mean,
                   ms=float(np.median(times)), ms_min=float(np.min(times)), cpu_ms=float(np.median(cpu)),
                   crossings=len(res.crossings), decided=sum(c.over is not None for c in res.crossings))
        npz = folder / f'{name}_mbest_paths.npz'
        if npz.exists():
            z = np.load(npz)
            paths = [z[k].astype(float) for k in sorted(z.files, key=lambda k: int(k[4:]))]
            objs = [PerceivedObject(p, width_along(p, res.segmentation), False) for p in paths]
            row['mbest_found'] = len(paths)
            row['mbest_dice'] = instance_dice(render_instances(objs, [], gt.shape), gt)[0]
        rows.append(row)
        print(f"{name}: {row['found']}/{row['rods']} objects, DICE {pooled:.4f} (mean {mean:.4f}), "
              f"{row['ms']:.1f} ms (min {row['ms_min']:.1f}, CPU {row['cpu_ms']:.1f})"
              + (f"; published mBEST paths DICE {row['mbest_dice']:.4f}" if 'mbest_dice' in row else ''))
    return rows


def drawn_cases(shared: Path):
    rng = np.random.default_rng(2024)
    cases = []
    for name, curve in example_curves(600).items():
        cases.append((name, curve, 600))
    pattern_dir = shared / 'reference' / 'rod_deployment' / 'patterns'
    for f in sorted(glob.glob(str(pattern_dir / '*.txt'))):
        p = np.loadtxt(f)[:, :2]
        span = (p.max(axis=0) - p.min(axis=0)).max()
        scale = 480.0 / max(span, 1e-9)                    # metres -> pixels, 480 px across
        rows = 60 + (p[:, 1].max() - p[:, 1]) * scale      # y up -> row down
        cols = 60 + (p[:, 0] - p[:, 0].min()) * scale
        cases.append((f'paper {Path(f).stem}', np.stack([rows, cols], axis=1), 600))
    for k in range(6):
        cases.append((f'random {k}', random_rod_curve(rng, (600, 600), rng.uniform(600, 1400), 30.0), 600))
    return cases


def bench_drawn(shared: Path):
    rows = []
    for name, curve, size in drawn_cases(shared):
        for width in (3.0, 6.0, 12.0):
            img = draw_strokes((size, size), [curve], [width], [(40, 30, 30)], background=(235, 235, 228),
                               noise_std=3.0, gradient=0.25, blur_sigma=0.8, seed=int(width))
            try:
                res = perceive(img)
            except ValueError as exc:
                rows.append(dict(case=name, width=width, found=0, error=str(exc)))
                continue
            obj = max(res.objects, key=lambda o: o.length_px())
            ref = curve
            closed = obj.closed
            if closed and not np.allclose(ref[0], ref[-1]):
                ref = np.vstack([ref, ref[:1]])
            err = centreline_rms(obj.points, ref)
            eq17 = arc_length_error(obj.points, ref) if not closed else {'mean_px': float('nan')}
            rows.append(dict(case=name, width=width, found=len(res.objects), rms=err['rms_px'],
                             max=err['max_px'], end=err['end_error_px'] if not closed else float('nan'),
                             eq17=eq17['mean_px'], width_est=obj.width_px))
    return rows


def random_rod_scenes(n: int, seed: int):
    """(trial, image, curves, widths, textured) of ``n`` random scenes of 1-3 rods (500 x 700 px), drawn from
    ``seed``: the scenes of :func:`bench_random_scenes` (and of ``perception_equivalence.py``)."""
    rng = np.random.default_rng(seed)
    palette = [(90, 90, 230), (60, 220, 200), (200, 200, 60), (50, 200, 50), (230, 120, 200), (40, 140, 250)]
    shape = (500, 700)
    for trial in range(n):
        k = 1 + trial % 3
        widths = list(rng.uniform(5, 16, k))
        curves = [random_rod_curve(rng, shape, rng.uniform(500, 1100), 4 * w) for w in widths]
        colours = [palette[i] for i in rng.choice(len(palette), k, replace=False)]
        textured = trial % 2 == 1
        img = draw_strokes(shape, curves, widths, colours, background=(120, 100, 80) if textured else (15, 15, 15),
                           noise_std=4, blur_sigma=0.8, texture=12.0 if textured else 0.0, seed=trial)
        yield trial, img, curves, widths, textured


def bench_random_scenes(n: int, seed: int = 7):
    rows = []
    for trial, img, curves, widths, textured in random_rod_scenes(n, seed):
        k, shape = len(curves), img.shape[:2]
        gt = np.zeros(shape, np.uint8)
        for i, (c, w) in enumerate(zip(curves, widths)):
            gt[stroke_coverage(shape, c, w) >= 0.5] = i + 1
        try:
            res = perceive(img)
            dice = instance_dice(render_instances(res.objects, res.crossings, shape), gt)[0]
            found = len(res.objects)
        except ValueError:
            dice, found = 0.0, 0
        rows.append(dict(trial=trial, rods=k, found=found, dice=dice, textured=textured, seed=seed))
    return rows


def markdown(mbest, drawn, scenes, repeats, data, load_start=None):
    cpu = os.cpu_count()
    load = os.getloadavg()
    lines = ['# Perception benchmark (`benchmarks/perception_mbest.py`)', '',
             f'Machine: {platform.processor() or platform.machine()}, {cpu} logical CPUs, Python '
             f'{platform.python_version()}, OpenCV {cv2.__version__}; load average at the start '
             f'{", ".join(f"{v:.1f}" for v in load_start or load)}, at the end '
             f'{", ".join(f"{v:.1f}" for v in load)} (timings are medians of {repeats} runs per image, image '
             'in memory; a loaded machine inflates the wall clock: compare the load average with the CPU count; '
             'CPU ms = process CPU time of all threads, which other processes inflate less).', '']
    if mbest:
        lines += ['## Published mBEST photos (896 x 672)', '',
                  f'Data: `{data}/mBEST` (read in place). Instance DICE: each perceived centreline drawn with its '
                  'measured width (pixel centres within half the width), upper object drawn last where the '
                  'crossing order was decided, matched one-to-one to the ground-truth instances (Hungarian); '
                  '"pooled" = 2 sum|P_k & G_k| / (sum|P| + sum|G|), "mean" = mean over instances. '
                  '"mBEST paths" = the published code\'s paths drawn the same way with our width estimate and '
                  'no over/under order (reference only; the published code scored 0.955-0.966 on its own '
                  'rendering over 30 images per set).', '',
                  '| image | rods | found | DICE pooled | DICE mean | crossings (order decided) | median ms | min ms '
                  '| CPU ms | mBEST paths DICE |',
                  '|---|---|---|---|---|---|---|---|---|---|']
        for r in mbest:
            lines.append(f"| {r['image']} | {r['rods']} | {r['found']} | {r['dice']:.4f} | {r['dice_mean']:.4f} | "
                         f"{r['crossings']} ({r['decided']}) | {r['ms']:.1f} | {r['ms_min']:.1f} | {r['cpu_ms']:.1f} | "
                         f"{r.get('mbest_dice', float('nan')):.4f} |")
        for s in ('S1', 'S2', 'S3'):
            rs = [r for r in mbest if r['image'].startswith(s)]
            if rs:
                lines.append(f"| **{s}** | | {sum(r['found'] == r['rods'] for r in rs)}/{len(rs)} right | "
                             f"{np.mean([r['dice'] for r in rs]):.4f} | "
                             f"{np.mean([r['dice_mean'] for r in rs]):.4f} | | "
                             f"{np.median([r['ms'] for r in rs]):.1f} | | {np.median([r['cpu_ms'] for r in rs]):.1f} | "
                             f"{np.mean([r.get('mbest_dice', np.nan) for r in rs]):.4f} |")
        lines += ['', f"All images: right count {sum(r['found'] == r['rods'] for r in mbest)}/{len(mbest)}, "
                  f"DICE min {min(r['dice'] for r in mbest):.4f}, mean {np.mean([r['dice'] for r in mbest]):.4f}; "
                  f"median time {np.median([r['ms'] for r in mbest]):.1f} ms wall clock, "
                  f"{np.median([r['cpu_ms'] for r in mbest]):.1f} ms CPU (all threads), best run "
                  f"{np.median([r['ms_min'] for r in mbest]):.1f} ms (targets: every count right, DICE >= 0.97, "
                  '<= 10 ms median per image on 2 cores).', '']
    else:
        lines += ['## Published mBEST photos', '', f'Skipped: `{data}/mBEST` not found.', '']
    lines += ['## Drawn patterns (synthetic strokes of known centreline)', '',
              'Dark ink on paper (shading 25 % across, noise 3, blur 0.8 px), 600 x 600 px. RMS: distances from the '
              'perceived path to the drawn curve and back, pooled [px]; end: worse end point error [px]; Eq. 17: '
              'mean distance after resampling both to 50 points by arc length [px] (open curves).', '',
              '| curve | width px | found | RMS px | max px | end px | Eq. 17 px | width est. px |',
              '|---|---|---|---|---|---|---|---|']
    for r in drawn:
        if 'error' in r:
            lines.append(f"| {r['case']} | {r['width']:g} | 0 | error: {r['error']} | | | | |")
            continue
        lines.append(f"| {r['case']} | {r['width']:g} | {r['found']} | {r['rms']:.3f} | {r['max']:.2f} | "
                     f"{r['end']:.2f} | {r['eq17']:.2f} | {r['width_est']:.2f} |")
    ok = [r for r in drawn if 'rms' in r]
    lines += ['', f"RMS: max {max(r['rms'] for r in ok):.3f} px, median {np.median([r['rms'] for r in ok]):.3f} px "
              f"over {len(ok)} strokes; {sum(r['rms'] <= 1.0 for r in ok)}/{len(drawn)} within the 1 px bar.", '']
    if scenes:
        lines += ['## Random synthetic rod scenes', '',
                  'Scenes of 1-3 rods (widths 5-16 px, minimum bend radius 4 widths, random distinct colours, '
                  'dark or textured table, 700 x 500 px); ground truth = pixels at least half covered, the rod '
                  'drawn last on top. Development set: seed 7 (failures inspected to find the rules; two more '
                  'seeds, 2027 and 99, were used to check them); held-out set: seed 4242, run only once the '
                  'rules were fixed.', '',
                  '| set | rods | scenes | right count | DICE mean | DICE median | DICE mean, right count |',
                  '|---|---|---|---|---|---|---|']
        for seed, name in ((7, 'development'), (4242, 'held out')):
            rows = [r for r in scenes if r['seed'] == seed]
            for k in (1, 2, 3, None):
                rs = [r for r in rows if k is None or r['rods'] == k]
                if not rs:
                    continue
                right = [r['dice'] for r in rs if r['found'] == r['rods']]
                lines.append(f"| {name} | {k or 'all'} | {len(rs)} | {len(right)} | "
                             f"{np.mean([r['dice'] for r in rs]):.4f} | {np.median([r['dice'] for r in rs]):.4f} | "
                             f"{np.mean(right or [0]):.4f} |")
        lines.append('')
    return '\n'.join(lines) + '\n'


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--data', default=str(ROOT.parent / 'shared' / 'data' / 'dlo_images'))
    parser.add_argument('--shared', default=str(ROOT.parent / 'shared'))
    parser.add_argument('--repeats', type=int, default=20)
    parser.add_argument('--scenes', type=int, default=30, help='development scenes (seed 7)')
    parser.add_argument('--heldout-scenes', type=int, default=60, help='held-out scenes (seed 4242)')
    parser.add_argument('--out', default=None, help='results file (default: see --commit-results)')
    add_results_argument(parser)
    parser.add_argument('--json', help='also write the raw numbers as JSON')
    args = parser.parse_args()
    args.out = args.out or str(results_path(args, 'perception_mbest.md'))
    data = Path(args.data)
    load_start = os.getloadavg()
    mbest = bench_mbest(data, args.repeats) if (data / 'mBEST').is_dir() else []
    drawn = bench_drawn(Path(args.shared))
    scenes = bench_random_scenes(args.scenes, 7) + bench_random_scenes(args.heldout_scenes, 4242)
    text = markdown(mbest, drawn, scenes, args.repeats, os.path.relpath(data, ROOT), load_start)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(text)
    print(text)
    if args.json:
        Path(args.json).write_text(json.dumps(dict(mbest=mbest, drawn=drawn, scenes=scenes), indent=1,
                                              default=float))


if __name__ == '__main__':
    main()
