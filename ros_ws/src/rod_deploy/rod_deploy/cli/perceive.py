"""``rod-deploy perceive``: ordered centrelines of drawn strokes or rods in a photo, in table metres.

    rod-deploy perceive --image IMG [--m-per-px S [--origin ROW COL] | --homography H.txt] --out path.csv
                        [--overlay overlay.png] [--pattern pattern.txt] [--deployed-out deployed.csv
                        [--start-near X Y]] [--object K] [--timing]

Writes ``path.csv`` (header ``object,row,col,x,y``: object ids from 0 by decreasing length, the points of
each object in order from one end, pixels and table metres), optionally an overlay PNG and the contract's
pattern text file of one object. ``--deployed-out`` writes one object (``--object``, default the longest) as
the contract's deployed shape (CSV ``x,y`` in metres, ordered from the first deployed end), ready for
``rod-deploy evaluate --deployed``: it starts at the end nearest to ``--start-near X Y`` (table metres; a
closed path starts at its point nearest to it), else at the path's first point (its leftmost end). Mapping: ``--m-per-px`` with ``--origin`` (default: the bottom-left pixel
centre, so the image covers x >= 0, y >= 0) or ``--homography``; without either, x and y are pixel units
in the same axes (scale 1) and no pattern file can be written. ``--timing`` prints the median processing
time (perception and mapping; no process start, no image loading) over ``--repeats`` runs.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from rod_deploy.cli.main import CliError


def register(subparsers):
    import argparse
    p = subparsers.add_parser(
        'perceive', help='ordered centrelines of strokes or rods in an image (path.csv, overlay, pattern)',
        description='Ordered centrelines of drawn strokes or rods in a photo, in table metres.',
        epilog=__doc__.split('\n\n', 2)[2], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--image', required=True, help='PNG/JPEG photo of drawn strokes or rods')
    mapping = p.add_mutually_exclusive_group()
    mapping.add_argument('--m-per-px', type=float, help='table metres per pixel s: x = (col - c0) s, y = (r0 - row) s')
    mapping.add_argument('--homography', help='text file with the 3x3 H of (x, y, 1) ~ H (col, row, 1)')
    p.add_argument('--origin', type=float, nargs=2, metavar=('ROW', 'COL'),
                   help='origin pixel (r0, c0) for --m-per-px (default: bottom-left pixel centre)')
    p.add_argument('--out', required=True, help='path.csv to write (object,row,col,x,y)')
    p.add_argument('--overlay', help='PNG to write: the paths, their direction and crossing decisions')
    p.add_argument('--pattern', help='pattern text file (x y z per line, metres) of one object')
    p.add_argument('--deployed-out', help="deployed shape CSV to write (contract 'x,y', metres) of one object, "
                                          'for rod-deploy evaluate')
    p.add_argument('--start-near', type=float, nargs=2, metavar=('X', 'Y'),
                   help='--deployed-out starts at the object end nearest to this table point [m] '
                        '(default: the leftmost end)')
    p.add_argument('--object', type=int, default=0,
                   help='object written to --pattern / --deployed-out (default 0, the longest)')
    p.add_argument('--step-px', type=float, default=1.0, help='point spacing along each path [px] (default 1)')
    p.add_argument('--segmentation', choices=('contrast', 'dark', 'bright'), default='contrast',
                   help='foreground evidence: any colour difference from the background (default), '
                        'darker only (ink on paper) or brighter only')
    p.add_argument('--timing', action='store_true', help='print the median processing time per image')
    p.add_argument('--repeats', type=int, default=20, help='runs for --timing (default 20)')
    p.set_defaults(func=run)


def _load_image(path):
    import cv2
    path = Path(path)
    if not path.is_file():
        raise CliError(f'image {path} does not exist')
    if path.stat().st_size == 0:
        raise CliError(f'image {path} is empty (0 bytes)')
    try:
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    except cv2.error as exc:
        raise CliError(f'cannot read image {path}: {exc.err}') from None
    if img is None or img.size == 0:
        raise CliError(f'cannot read image {path} (not an image OpenCV can decode, or too large)')
    return img


def _mapping(args, image_shape):
    from rod_deploy.perception.pixel_mapping import MappingError, ScaleOrigin, default_origin, load_homography
    try:
        if args.homography:
            if args.origin:
                raise CliError('--origin applies to --m-per-px, not to --homography')
            m = load_homography(args.homography)
            m.check_image(image_shape)
            return m, True
        origin = tuple(args.origin) if args.origin else default_origin(image_shape)
        if args.m_per_px is not None:
            return ScaleOrigin(args.m_per_px, *origin), True
        return ScaleOrigin(1.0, *origin), False
    except MappingError as exc:
        raise CliError(str(exc)) from None


def run(args) -> int:
    from rod_deploy.perception.path_io import write_path_csv, write_pattern_file
    from rod_deploy.perception.pipeline import PerceptionConfig, PerceptionError, perceive
    from rod_deploy.perception.segmentation import SegmentationConfig

    if not args.step_px > 0:
        raise CliError(f'--step-px must be > 0, got {args.step_px}')
    if args.timing and args.repeats < 1:
        raise CliError(f'--repeats must be >= 1, got {args.repeats}')
    image = _load_image(args.image)
    mapping, metric = _mapping(args, image.shape)
    if args.pattern and not metric:
        raise CliError('--pattern needs --m-per-px or --homography (the pattern file is in metres)')
    if args.deployed_out and not metric:
        raise CliError('--deployed-out needs --m-per-px or --homography (the deployed shape is in metres)')
    if args.start_near and not args.deployed_out:
        raise CliError('--start-near applies to --deployed-out')
    if args.start_near and not np.all(np.isfinite(args.start_near)):
        raise CliError(f'--start-near must be finite, got {args.start_near}')
    config = PerceptionConfig(segmentation=SegmentationConfig(method=args.segmentation), step_px=args.step_px)

    def process():
        result = perceive(image, config)
        xy = [np.stack(mapping.to_table(o.points[:, 0], o.points[:, 1]), axis=1) for o in result.objects]
        return result, xy

    try:
        result, xy = process()
    except PerceptionError as exc:
        raise CliError(f'{args.image}: {exc}') from None
    if not all(np.all(np.isfinite(p)) for p in xy):
        raise CliError('the mapping sends some path points to infinity; check the homography')
    if (args.pattern or args.deployed_out) and not 0 <= args.object < len(result.objects):
        raise CliError(f'--object {args.object}: the image has objects 0..{len(result.objects) - 1}')

    out = Path(args.out)
    try:
        write_path_csv(out, [o.points for o in result.objects], xy)
        if args.pattern:
            write_pattern_file(args.pattern, xy[args.object])
        if args.deployed_out:
            from rod_deploy.deployment.metrics import write_deployed_csv
            from rod_deploy.perception.path_io import deployed_order
            write_deployed_csv(args.deployed_out, deployed_order(xy[args.object], result.objects[args.object].closed,
                                                                 args.start_near))
        if args.overlay:
            import cv2
            from rod_deploy.perception.overlay import draw_overlay
            from rod_deploy.perception.segmentation import as_bgr
            m_per_px = getattr(mapping, 'm_per_px', None) if metric else None
            if not cv2.imwrite(str(args.overlay), draw_overlay(as_bgr(image), result.objects, result.crossings,
                                                               m_per_px)):
                raise CliError(f'cannot write overlay {args.overlay} (use a .png or .jpg name)')
    except OSError as exc:
        raise CliError(f'cannot write output: {exc}') from None

    print(f'{args.image}: {result.summary()}')
    if result.scale != 1.0:
        print(f'note: the image has {image.shape[0] * image.shape[1] / 1e6:.1f} Mpx; processed at scale '
              f'{result.scale:.3f}, coordinates are in full-resolution pixels')
    print(f'mapping: {mapping.describe()}' if metric else
          'mapping: none given (--m-per-px or --homography); x and y are in pixels (scale 1, origin at the '
          'bottom-left pixel)')
    if len(result.objects) > 1 and (args.pattern or args.deployed_out):
        print(f'note: {len(result.objects)} objects; the pattern / deployed file holds object {args.object} only',
              file=sys.stderr)
    print(f'wrote {out}' + (f', {args.pattern}' if args.pattern else '') +
          (f', {args.deployed_out}' if args.deployed_out else '') +
          (f', {args.overlay}' if args.overlay else ''))
    if args.timing:
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            process()
            times.append((time.perf_counter() - t0) * 1e3)
        print(f'timing: median {np.median(times):.1f} ms per image over {args.repeats} runs '
              f'(min {np.min(times):.1f}, max {np.max(times):.1f}); image {image.shape[1]} x {image.shape[0]} px')
    return 0
