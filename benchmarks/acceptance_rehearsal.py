"""Acceptance rehearsal of issue #10: held-out drawn shapes, through the command line exactly as the acceptance calls it.

    python benchmarks/acceptance_rehearsal.py [--only NAME,...] [--no-sim] [--errors-only] [--commit-results]
    PYTHONPATH=ros_ws/src/rod_deploy .venv-bench/bin/python benchmarks/acceptance_rehearsal.py --commit-results \
        --elastica out/acceptance/RUN ...      # replay some runs in PyElastica (make bench-env), added to the table

Shapes drawn here by code, in metres, for this rehearsal only (none of them was used to develop or tune anything):
a cursive letter e that crosses itself, a figure 8 (closed), an outward spiral, a heart (two cusps: must be refused),
a zig-zag with rounded corners, the digit 3, a 10 cm hook and the same hook drawn backwards, a 1.5 m gentle wave
(on a 2 m cable), the letter e written in millimetres (must be refused), the letter e moved to negative
coordinates and turned by 130 degrees, a double arc given with a z column, an arch sampled with 2000 and with 8
points, and a rounded square written as a CSV with a header and comments.

Rods: the paper's rods #2 (L_gb 3.2 cm, h 1.6 mm, 0.885 m) and #3 (3.4 cm, 2.0 mm, 0.89 m) and a 2 m cable (h 3 mm,
E 10 MPa, rho 1400 kg/m^3: L_gb 9.36 cm), each written in the contract's three forms (L_gb, loop_height,
youngs_modulus + density). Every run is three processes, timed from outside:

    rod-deploy plan --pattern P --rod ROD.yaml --method M --out traj.csv
    rod-deploy simulate --traj traj.csv --rod ROD.yaml --out deployed.csv --plot deployed.png
    rod-deploy evaluate --pattern P --deployed deployed.csv

then bad inputs, each of which must give exit status 2, one line on stderr naming the problem, no traceback and no
output file. Writes ``acceptance_rehearsal.md`` (and the files of every run under ``out/acceptance/``).

The shapes above have been looked at while developing since. ``--set fresh`` (round 9) is a second set, drawn once and
not tuned on: cursive a, m and w, digits 5, 7 and 9, a rounded star, a clothoid, a mouse-drawn polyline, a closed egg,
a paperclip in a points file with unusual but valid formatting (and a flow-style rod YAML), a 0.855 m meander near rod
#2's length limit and a cursive l given as a PNG with ``--m-per-px``, on the paper's rods #1-#3, each with every
method, and 20 bad inputs of plan, simulate and evaluate (``acceptance_rehearsal_fresh.md``, runs under
``out/acceptance/fresh/``):

    python benchmarks/acceptance_rehearsal.py --set fresh [--only S,...] [--methods nn,...] [--plan-args '--start tangent']
        [--add-runs]                 # add runs to the last results instead of starting new ones
"""
from __future__ import annotations

import argparse
import fcntl
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from scipy.integrate import cumulative_trapezoid
from scipy.interpolate import splev, splprep

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / 'out' / 'acceptance'
G = 9.81
LOOP = 0.9066

# ------------------------------------------------------------------------------------------------ rods
RODS = {'rod1': dict(length=0.875, radius=0.0016, L_gb=0.018, density=1180.0),
        'rod2': dict(length=0.885, radius=0.0016, L_gb=0.032, density=1180.0),
        'rod3': dict(length=0.89, radius=0.002, L_gb=0.034, density=1180.0),
        'cable': dict(length=2.0, radius=0.003, youngs_modulus=1.0e7, density=1400.0)}


def rod_yaml(name, form):
    """The rod ``name`` in the contract's form ``L_gb``, ``loop_height`` or ``E_rho``, with friction 0.5; ``flow``:
    the E_rho form written as one YAML flow mapping, the exponents without a decimal point (PyYAML reads ``1e7`` as a
    string), an integer density and a document marker (valid YAML, the contract's fields)."""
    r = RODS[name]
    h = r['radius']
    if 'L_gb' in r:
        lgb = r['L_gb']
        E = 8.0 * r['density'] * G * lgb ** 3 / h ** 2
    else:
        E = r['youngs_modulus']
        lgb = (E * h ** 2 / (8.0 * r['density'] * G)) ** (1.0 / 3.0)
    if form == 'flow':
        return (f'---\n# {name}, flow form\n{{radius: {h * 1e3:g}e-3, friction: 0.5, density: {int(r["density"])}, '
                f'youngs_modulus: {E / 1e6:.6f}e6, length: {r["length"]}}}\n')
    lines = [f'# {name}, {form} form', f'length: {r["length"]}', f'radius: {h}']
    if form == 'L_gb':
        lines.append(f'L_gb: {lgb!r}')
    elif form == 'loop_height':
        lines.append(f'loop_height: {LOOP * lgb!r}   # L_gb = h_f / 0.9066')
    else:
        lines += [f'youngs_modulus: {E!r}', f'density: {r["density"]}']
    lines.append('friction: 0.5')
    return '\n'.join(lines) + '\n'


# ------------------------------------------------------------------------------------------------ shapes
def _spline(pts, n=400):
    tck, _ = splprep(np.asarray(pts, float).T, s=0, k=3)
    return np.column_stack(splev(np.linspace(0, 1, n), tck))


def _arc(center, radius, a0, a1, n):
    a = np.linspace(a0, a1, n)
    return np.column_stack([center[0] + radius * np.cos(a), center[1] + radius * np.sin(a)])


def _polyline_rounded(corners, radius, n_arc=30, n_line=30):
    """A polyline through ``corners`` with each inner corner replaced by a circular arc of ``radius``."""
    c = np.asarray(corners, float)
    out = [c[0]]
    for k in range(1, len(c) - 1):
        a, b, d = c[k - 1], c[k], c[k + 1]
        u1, u2 = (b - a) / np.linalg.norm(b - a), (d - b) / np.linalg.norm(d - b)
        turn = np.arctan2(u1[0] * u2[1] - u1[1] * u2[0], u1 @ u2)
        cut = radius * np.tan(abs(turn) / 2)
        p1 = b - u1 * cut
        normal = np.array([-u1[1], u1[0]]) * np.sign(turn)
        center = p1 + normal * radius
        a0 = np.arctan2(*(p1 - center)[::-1])
        seg = np.linspace(out[-1], p1, n_line)[1:]
        out.extend(seg)
        out.extend(_arc(center, radius, a0, a0 + turn, n_arc)[1:])
    out.extend(np.linspace(out[-1], c[-1], n_line)[1:])
    return np.array(out)


def shapes():
    """{name: (points (n, 2) [m], file format, what it tests)}."""
    out = {}
    t = np.linspace(-0.75 * np.pi, 1.25 * np.pi, 500)         # cursive e: a prolate trochoid, crossing itself
    e = np.column_stack([0.025 * t - 0.07 * np.sin(t), 0.07 * np.cos(t)])
    out['letter_e'] = (e - e[0], 'xy', 'cursive e, crosses itself')
    t = np.linspace(0, 2 * np.pi, 600)                         # lemniscate of Gerono, closed
    out['figure8'] = (np.column_stack([0.12 * np.cos(t), 0.12 * np.sin(t) * np.cos(t)]), 'xy', 'closed, crossing')
    th = np.linspace(0, 3.5 * np.pi, 700)                      # outward Archimedean spiral from r = 3.5 cm
    r = 0.035 + 0.045 * th / (2 * np.pi)
    out['spiral_out'] = (np.column_stack([r * np.cos(th), r * np.sin(th)]), 'xy', 'tight start, 0.82 m long')
    t = np.linspace(0, 2 * np.pi, 501)[:-1] + 0.003            # the classic heart: cusps at t = 0 and pi (the
    heart = 0.2 / 32 * np.column_stack([16 * np.sin(t) ** 3,     # samples beside them, as a drawing would be)
                                        13 * np.cos(t) - 5 * np.cos(2 * t) - 2 * np.cos(3 * t) - np.cos(4 * t)])
    out['heart'] = (heart, 'xy', 'two cusps: must be refused')
    out['zigzag_4_corners'] = (np.array([[0, 0], [0.05, 0.05], [0.1, 0], [0.15, 0.05]]), 'xy',
                               'a zig-zag given by its 4 corners only (sharp corners meant?)')
    corners = [[0, 0]] + [[0.07 * k, 0.07 * (k % 2)] for k in range(1, 7)]
    out['zigzag_rounded'] = (_polyline_rounded(corners, 0.025), 'xy', '90-degree corners, radius 2.5 cm')
    out['digit3'] = (_spline([[-0.055, 0.13], [0.0, 0.16], [0.05, 0.135], [0.045, 0.095], [0.0, 0.08],
                              [0.055, 0.055], [0.06, 0.0], [0.0, -0.03], [-0.06, -0.005]]), 'xy', 'hand-drawn 3')
    hook = np.vstack([np.column_stack([np.zeros(60), np.linspace(0.0, 0.05, 60)]),
                      _arc((-0.016, 0.05), 0.016, 0.0, np.pi, 80)[1:]])
    out['hook_10cm'] = (hook, 'xy', 'short: 10 cm, radius 1.6 cm at its end')
    out['hook_reversed'] = (hook[::-1].copy(), 'xy', 'the hook from its curled end')
    x = np.linspace(0.0, 1.4, 1500)
    out['long_wave_1p5m'] = (np.column_stack([x, 0.05 * np.sin(2 * np.pi * x / 0.5)]), 'xy', '1.5 m, on the cable')
    out['letter_e_mm'] = (1000 * (e - e[0]), 'xy', 'the e written in millimetres: must be refused')
    c, s = np.cos(np.radians(130)), np.sin(np.radians(130))
    out['letter_e_moved'] = ((e - e[0]) @ np.array([[c, s], [-s, c]]) + [-0.75, -0.42], 'xy',
                             'the e turned 130 deg, at (-0.75, -0.42) m')
    arc1 = _arc((0.0, -0.08), 0.08, np.pi / 2, np.pi / 2 - 2.1, 150)
    arc2 = _arc(2 * arc1[-1] - (0.0, -0.08), 0.08, np.pi / 2 - 2.1 + np.pi, np.pi / 2 + np.pi, 150)[1:]
    out['double_arc_xyz'] = (np.vstack([arc1, arc2]), 'xyz', 'x y z lines (z = 0)')
    x = np.linspace(0.0, 0.45, 2000)
    out['arch_dense_2000'] = (np.column_stack([x, 0.12 * np.sin(np.pi * x / 0.45)]), 'xy', '2000 points')
    x = np.linspace(0.0, 0.45, 8)
    out['arch_sparse_8'] = (np.column_stack([x, 0.12 * np.sin(np.pi * x / 0.45)]), 'xy', 'the same arch, 8 points')
    sq = _polyline_rounded([[0, 0], [0.15, 0], [0.15, 0.15], [0, 0.15], [0, 0.0], [0.075, 0.0]], 0.03)
    out['rounded_square_csv'] = (sq, 'csv', 'CSV "x, y" with a header line and # comments, closed')
    return out


# ------------------------------------------------------------------------------------------------ the fresh set
#: metres per pixel of the fresh set's drawn image (a 520 x 520 px drawing: 26 cm square)
IMAGE_M_PER_PX = 0.0005


def _spline_closed(pts, n=400):
    """A closed cubic spline through ``pts`` (n samples, the first point repeated at the end)."""
    p = np.asarray(pts, float)
    tck, _ = splprep(np.vstack([p, p[:1]]).T, s=0, k=3, per=1)
    return np.column_stack(splev(np.linspace(0, 1, n), tck))


def _mouse(curve, seed, px=0.0005, rate_hz=60.0):
    """``curve`` as a mouse gives it: samples at ``rate_hz`` while the hand speeds up on the straights and slows in
    the bends (3-70 cm/s), a tremor of 0.3 mm, rounded to the screen's pixels (``px`` metres), consecutive equal
    samples dropped (the contract refuses repeated points); returns (points, the points with a pause: one sample
    repeated 3 times, as a mouse at rest reports it)."""
    rng = np.random.default_rng(seed)
    seg = np.linalg.norm(np.diff(curve, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    d1 = np.gradient(curve, s, axis=0)
    d2 = np.gradient(d1, s, axis=0)
    kappa = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    speed = np.clip(0.35 / (1.0 + 0.04 * kappa), 0.03, 0.5) * (1 + 0.4 * np.sin(s * 37.0))    # m/s
    t = np.concatenate([[0.0], np.cumsum(np.diff(s) / (0.5 * (speed[1:] + speed[:-1])))])
    ts = np.arange(0.0, t[-1], 1.0 / rate_hz)
    ss = np.interp(ts, t, s)
    pts = np.column_stack([np.interp(ss, s, curve[:, 0]), np.interp(ss, s, curve[:, 1])])
    pts = np.vstack([pts, curve[-1:]])
    pts = np.round((pts + rng.normal(0.0, 0.0003, pts.shape)) / px) * px
    pts = pts[np.concatenate([[True], np.any(np.diff(pts, axis=0) != 0, axis=1)])]
    k = len(pts) // 3                                    # the hand pauses there: the mouse reports 4 equal samples
    return pts, np.vstack([pts[:k], np.repeat(pts[k:k + 1], 3, axis=0), pts[k:]])


def fresh_shapes():
    """The second rehearsal set ({name: (points (n, 2) [m], file format, what it tests)}), drawn for round 9 and
    not looked at by anyone developing the planner: handwriting-sized letters and digits, a rounded star, a clothoid,
    a mouse-drawn polyline, a closed curve, a points file in unusual but valid formatting, a pattern near the rod's
    length limit and a drawn stroke given as an image."""
    out = {}
    out['cursive_a'] = (_spline([[0.04, 0.075], [0.0, 0.095], [-0.045, 0.06], [-0.04, 0.01], [0.0, -0.005],
                                 [0.035, 0.02], [0.05, 0.065], [0.065, 0.1], [0.09, 0.1], [0.09, 0.05],
                                 [0.095, 0.01], [0.125, 0.0], [0.155, 0.025]]), 'xy',
                        'cursive a: bowl, a loop over into the stem, exit stroke')
    out['cursive_m'] = (_spline([[-0.01, -0.005], [0.01, 0.02], [0.025, 0.065], [0.045, 0.09], [0.068, 0.065],
                                 [0.075, 0.02], [0.09, 0.0], [0.105, 0.02], [0.11, 0.065], [0.13, 0.09],
                                 [0.153, 0.065], [0.16, 0.02], [0.175, 0.0], [0.19, 0.02], [0.195, 0.065],
                                 [0.215, 0.09], [0.238, 0.065], [0.245, 0.02], [0.26, 0.0], [0.285, 0.005]]), 'xy',
                        'cursive m: three arches, bottoms of about 5 mm radius')
    out['cursive_w'] = (_spline([[-0.01, 0.1], [0.005, 0.06], [0.02, 0.015], [0.04, 0.0], [0.06, 0.015],
                                 [0.07, 0.06], [0.085, 0.09], [0.1, 0.06], [0.11, 0.015], [0.13, 0.0],
                                 [0.15, 0.015], [0.16, 0.06], [0.165, 0.09], [0.185, 0.08], [0.21, 0.07],
                                 [0.25, 0.075]]), 'xy', 'cursive w: valleys, a 3.5 mm top, exit flourish')
    out['digit5'] = (_spline([[0.075, 0.16], [0.04, 0.161], [0.01, 0.158], [-0.002, 0.14], [-0.008, 0.11],
                              [0.01, 0.1], [0.045, 0.098], [0.072, 0.07], [0.07, 0.03], [0.04, 0.0],
                              [0.0, -0.002], [-0.025, 0.012]]), 'xy', 'digit 5 in one stroke')
    out['digit7'] = (_polyline_rounded([[-0.05, 0.17], [0.07, 0.17], [0.02, 0.07], [0.0, 0.0]], 0.02), 'xy',
                     'digit 7: a 2 cm rounded corner of 117 degrees, then a kinked diagonal')
    a = np.linspace(0.35, 0.35 - 2 * np.pi, 300)                # clockwise from the loop's right side, then the tail
    loop = np.column_stack([0.045 * np.cos(a), 0.12 + 0.045 * np.sin(a)])
    tail = _spline([loop[-3], loop[-2], loop[-1], [0.05, 0.09], [0.05, 0.05], [0.04, 0.0], [0.01, -0.025]])
    out['digit9'] = (np.vstack([loop, tail[np.argmin(np.linalg.norm(tail - loop[-1], axis=1)) + 1:]]), 'xy',
                     'digit 9: the loop from its right side, the tail running beside its start')
    ang = np.pi / 2 + np.arange(10) * np.pi / 5
    rad = np.where(np.arange(10) % 2 == 0, 0.12, 0.055)
    tips = np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])
    mid = 0.5 * (tips[0] + tips[1])
    out['rounded_star'] = (_polyline_rounded(np.vstack([mid, tips[1:], tips[:1], mid]), 0.012), 'xy',
                           'five-pointed star, corners rounded by 1.2 cm, closed (ends at its first point)')
    s = np.linspace(0.0, 0.45, 900)                         # curvature rising linearly from 0 to 1 / 2.5 cm
    th = 0.5 * s ** 2 / (0.45 * 0.025)
    out['clothoid'] = (np.column_stack([cumulative_trapezoid(np.cos(th), s, initial=0),
                                        cumulative_trapezoid(np.sin(th), s, initial=0)]), 'xy',
                       'Euler spiral, 0.45 m, radius down to 2.5 cm')
    scribble = _spline([[0.0, 0.0], [0.06, 0.03], [0.1, 0.09], [0.07, 0.14], [0.02, 0.12], [0.04, 0.07],
                        [0.12, 0.05], [0.19, 0.08], [0.24, 0.04], [0.3, 0.03]], n=2000)
    mouse, mouse_raw = _mouse(scribble, seed=9)
    out['mouse_polyline'] = (mouse, 'xy', f'mouse-drawn: {len(mouse)} samples 0.5-{1e3 * np.linalg.norm(np.diff(mouse, axis=0), axis=1).max():.0f} mm apart, '
                             '0.3 mm tremor, 0.5 mm pixels')
    out['mouse_polyline_paused'] = (mouse_raw, 'xy', 'the same with the repeated samples of the paused mouse')
    egg = _spline_closed([[0.09, 0.0], [0.06, 0.05], [0.0, 0.065], [-0.07, 0.045], [-0.1, 0.0], [-0.07, -0.045],
                          [0.0, -0.065], [0.06, -0.05]], n=500)
    k0 = 310                                                 # start on its blunt side, the curve rolled to start there
    out['closed_egg'] = (np.vstack([egg[k0:-1], egg[:k0], egg[k0:k0 + 1]]), 'xy',
                         'closed egg 19 x 13 cm, the first point repeated at the end')
    out['paperclip_oddformat'] = (_polyline_rounded([[0.0, 0.0], [0.16, 0.0], [0.16, 0.07], [0.02, 0.07],
                                                     [0.02, 0.02], [0.13, 0.02]], 0.03), 'odd',
                                  'paperclip; BOM, CRLF, tabs, "x y z" header, 1.6E-01, +0.07, .05, z -0.0 / 1e-4, '
                                  'blank and comment lines; drawn wrong: two 3 cm roundings on a 5 cm side overlap '
                                  '(a kink at (0.02, 0.045) m)')
    out['paperclip2_oddformat'] = (_polyline_rounded([[0.0, 0.0], [0.16, 0.0], [0.16, 0.08], [0.02, 0.08],
                                                      [0.02, 0.015], [0.13, 0.015]], 0.025), 'odd',
                                   'the paperclip drawn right (2.5 cm roundings), the same formatting')
    x = np.linspace(0.0, 0.73, 3000)                         # a meander 0.855 m long (rod #2 allows 0.869 m)
    y = 0.06 * np.sin(2 * np.pi * x / 0.25)
    ds = np.hypot(np.gradient(x), np.gradient(y))
    keep = np.concatenate([[0.0], np.cumsum(ds[1:])]) <= 0.855
    out['long_meander_0p855m'] = (np.column_stack([x, y])[keep], 'xy', 'meander 0.855 m: near rod #2\'s 0.869 m limit')
    loop_l = _spline([[0.03, 0.02], [0.07, 0.06], [0.11, 0.13], [0.115, 0.2], [0.09, 0.225], [0.065, 0.2],
                      [0.075, 0.12], [0.11, 0.05], [0.15, 0.03], [0.2, 0.05]], n=600)
    out['cursive_l_image'] = (loop_l, 'png', f'a cursive l drawn as a PNG, 4 mm pen, {IMAGE_M_PER_PX * 1e3:g} mm '
                              'per pixel; crosses itself')
    return out


def write_png(path, xy, m_per_px=IMAGE_M_PER_PX, size_px=520, pen_px=8):
    """The stroke ``xy`` [m] drawn dark on white paper with a pen ``pen_px`` wide (the contract's default origin:
    the bottom-left pixel centre, x = col s, y = (rows - 1 - row) s)."""
    import cv2
    img = np.full((size_px, size_px, 3), 245, np.uint8)
    rng = np.random.default_rng(3)
    img = np.clip(img + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)     # paper texture
    cols = xy[:, 0] / m_per_px
    rows = (size_px - 1) - xy[:, 1] / m_per_px
    pts = np.round(np.column_stack([cols, rows]) * 16).astype(np.int32)           # 4 fractional bits
    cv2.polylines(img, [pts.reshape(-1, 1, 2)], False, (40, 35, 30), pen_px, cv2.LINE_AA, shift=4)
    cv2.imwrite(str(path), img)


def write_odd(path, xy):
    """A points file valid by the contract (x y [z] per line, metres) in unusual formatting: a UTF-8 byte-order
    mark, Windows line ends, a header line, tabs and runs of spaces, exponents, explicit + signs, numbers without a
    leading zero, z columns of -0.0 and 1e-4, blank and comment lines, trailing white space."""
    rows = ['\ufeff# paperclip, drawn for the acceptance rehearsal (round 9)', 'x\ty\tz', '']
    for k, (x, y) in enumerate(xy):
        fx = f'{x:.5E}' if k % 3 == 0 else (f'+{x:.6f}' if x >= 0 and k % 3 == 1 else f'{x:.6f}')
        fy = f'{y:.6f}'.replace('0.', '.', 1) if 0 <= y < 1 and k % 2 else f'{y:.6f}'
        z = ('-0.0', '0', '1e-4', '0.000000')[k % 4]
        sep = ('\t', '   ', ' \t ')[k % 3]
        rows.append(f'  {fx}{sep}{fy}{sep}{z}  ' + ('# corner' if k == 40 else ''))
        if k == 100:
            rows += ['', '# a comment line in the middle', '   ']
    path.write_bytes(('\r\n'.join(rows) + '\r\n').encode('utf-8'))


def write_pattern(path, xy, fmt):
    if fmt == 'png':
        return write_png(path, xy)
    if fmt == 'odd':
        return write_odd(path, xy)
    with open(path, 'w') as f:
        if fmt == 'csv':
            f.write('# drawn for the acceptance rehearsal\nx,y\n')
            for k, (x, y) in enumerate(xy):
                f.write(f'{x:.6f}, {y:.6f}' + ('   # corner' if k == 0 else '') + '\n')
        elif fmt == 'xyz':
            for x, y in xy:
                f.write(f'{x:.6f} {y:.6f} 0.000000\n')
        else:
            for x, y in xy:
                f.write(f'{x:.6f} {y:.6f}\n')


# ------------------------------------------------------------------------------------------------ runs
#: (shape, rod, rod form, method, simulate?[, extra plan arguments])
RUNS = [
    ('letter_e', 'rod3', 'L_gb', 'nn', True),
    ('letter_e', 'rod3', 'L_gb', 'numeric', True),
    ('letter_e', 'rod3', 'L_gb', 'intuitive', True),
    ('letter_e_moved', 'rod3', 'L_gb', 'nn', True),
    ('letter_e', 'rod2', 'loop_height', 'nn', True),
    ('figure8', 'rod3', 'loop_height', 'nn', True),
    ('figure8', 'rod3', 'loop_height', 'intuitive', True),
    ('spiral_out', 'rod3', 'E_rho', 'nn', True),
    ('heart', 'rod3', 'L_gb', 'nn', False),
    ('zigzag_rounded', 'rod3', 'L_gb', 'nn', True),
    ('zigzag_rounded', 'rod2', 'E_rho', 'nn', True),
    ('digit3', 'rod3', 'L_gb', 'nn', True),
    ('digit3', 'rod3', 'L_gb', 'numeric', True),
    ('hook_10cm', 'rod3', 'E_rho', 'nn', True),
    ('hook_reversed', 'rod3', 'E_rho', 'nn', True),
    ('hook_10cm', 'rod3', 'E_rho', 'intuitive', True),
    ('long_wave_1p5m', 'cable', 'E_rho', 'nn', True),
    ('letter_e_mm', 'rod3', 'L_gb', 'nn', False),
    ('double_arc_xyz', 'rod2', 'L_gb', 'nn', True),
    ('arch_dense_2000', 'rod3', 'loop_height', 'nn', True),
    ('arch_sparse_8', 'rod3', 'loop_height', 'nn', True),
    ('rounded_square_csv', 'rod3', 'L_gb', 'nn', True),
    ('zigzag_4_corners', 'rod3', 'L_gb', 'nn', False),
    # the same shapes with Alg. 4's tangent start (every node on the pattern): what the default start costs or gains
    ('letter_e', 'rod3', 'L_gb', 'nn', True, ('--start', 'tangent')),
    ('figure8', 'rod3', 'loop_height', 'nn', True, ('--start', 'tangent')),
    ('spiral_out', 'rod3', 'E_rho', 'nn', True, ('--start', 'tangent')),
    ('zigzag_rounded', 'rod3', 'L_gb', 'nn', True, ('--start', 'tangent')),
    ('rounded_square_csv', 'rod3', 'L_gb', 'nn', True, ('--start', 'tangent')),
]

#: the fresh set: each shape on one of the paper's rods #1-#3 (in one of the contract's forms), with every method
FRESH_RODS = {'cursive_a': ('rod3', 'L_gb'), 'cursive_m': ('rod1', 'loop_height'), 'cursive_w': ('rod1', 'E_rho'),
              'digit5': ('rod2', 'L_gb'), 'digit7': ('rod3', 'E_rho'), 'digit9': ('rod2', 'loop_height'),
              'rounded_star': ('rod3', 'loop_height'), 'clothoid': ('rod2', 'E_rho'),
              'mouse_polyline': ('rod3', 'L_gb'), 'closed_egg': ('rod1', 'L_gb'),
              'paperclip_oddformat': ('rod2', 'flow'), 'paperclip2_oddformat': ('rod2', 'flow'),
              'long_meander_0p855m': ('rod2', 'L_gb'),
              'cursive_l_image': ('rod3', 'L_gb')}
FRESH_RUNS = [(shape, rod, form, method, True) for shape, (rod, form) in FRESH_RODS.items()
              for method in ('nn', 'numeric', 'intuitive')]


def pattern_file(fmt):
    """(the pattern's file name, the extra arguments plan and evaluate need for it)."""
    if fmt == 'png':
        return 'pattern.png', ['--m-per-px', repr(IMAGE_M_PER_PX)]
    return ('pattern.csv' if fmt == 'csv' else 'pattern.txt'), []


def load_run_pattern(d):
    """The pattern of the run in folder ``d`` as the CLI reads it (an image through perception; in the benchmark
    environment, which has no OpenCV, the points perception gave when the run was made, ``pattern_perceived.txt``)."""
    from rod_deploy.planning.pattern_input import load_pattern
    if (Path(d) / 'pattern.png').exists() and (Path(d) / 'pattern_perceived.txt').exists():
        try:
            import cv2  # noqa: F401
        except ImportError:
            return load_pattern(Path(d) / 'pattern_perceived.txt')
    for name in ('pattern.csv', 'pattern.txt', 'pattern.png'):
        if (Path(d) / name).exists():
            return load_pattern(Path(d) / name, m_per_px=IMAGE_M_PER_PX if name.endswith('.png') else None)
    raise FileNotFoundError(f'no pattern in {d}')


def run_cli(args, cwd):
    """(exit status, stdout, stderr, wall s, cpu s) of one ``rod-deploy`` process (its own CPU time, from wait4: exact
    also when several runs go at once, ``--jobs``)."""
    exe = shutil.which('rod-deploy') or str(Path(sys.executable).parent / 'rod-deploy')
    t0 = time.perf_counter()
    with tempfile.TemporaryFile('w+') as fo, tempfile.TemporaryFile('w+') as fe:
        p = subprocess.Popen([exe, *args], cwd=cwd, stdout=fo, stderr=fe, text=True,
                             env={**os.environ, 'MPLBACKEND': 'Agg'})
        _, status, usage = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - t0
        fo.seek(0)
        fe.seek(0)
        stdout, stderr = fo.read(), fe.read()
    return p.returncode, stdout, stderr, wall, usage.ru_utime + usage.ru_stime


def _json(stdout):
    for line in stdout.splitlines()[::-1]:
        if line.startswith('{'):
            return json.loads(line)
    return None


def _notes(stderr):
    """The stderr lines that are neither progress bars nor empty."""
    return [ln.strip() for ln in stderr.replace('\r', '\n').splitlines()
            if ln.strip() and '%|' not in ln]


def do_run(shape, rod, form, method, simulate, shp, log, extra=()):
    d = WORK / (f'{shape}__{rod}_{form}__{method}' + ''.join(f'_{a.strip("-")}' for a in extra))
    d.mkdir(parents=True, exist_ok=True)
    pts, fmt, _ = shp[shape]
    name, pargs = pattern_file(fmt)
    for old in d.glob('pattern.*'):
        old.unlink()
    pat = d / name
    write_pattern(pat, pts, fmt)
    (d / 'pattern_perceived.txt').unlink(missing_ok=True)
    if fmt == 'png':                         # what perception makes of it, for the replay's scoring without OpenCV
        np.savetxt(d / 'pattern_perceived.txt', load_run_pattern(d), fmt='%.6f')
    (d / 'rod.yaml').write_text(rod_yaml(rod, form))
    row = {'shape': shape, 'rod': rod, 'form': form, 'method': method + ''.join(f' {a}' for a in extra),
           'dir': str(d.relative_to(ROOT))}
    for f in ('traj.csv', 'deployed.csv', 'deployed.png', 'plan.png'):
        (d / f).unlink(missing_ok=True)
    rc, so, se, w, c = run_cli(['plan', '--pattern', pat.name, *pargs, '--rod', 'rod.yaml', '--method', method,
                                '--out', 'traj.csv', '--plot', 'plan.png', '--quiet', *extra], d)
    row.update(plan_rc=rc, plan_wall=w, plan_cpu=c, plan=_json(so), plan_notes=_notes(se))
    log(f'{shape} {rod} {form} {method}: plan rc {rc} {w:.1f} s; {_notes(se)}')
    if rc != 0 or not simulate:
        return row
    rc, so, se, w, c = run_cli(['simulate', '--traj', 'traj.csv', '--rod', 'rod.yaml', '--out', 'deployed.csv',
                                '--plot', 'deployed.png', '--quiet'], d)
    row.update(sim_rc=rc, sim_wall=w, sim_cpu=c, sim=_json(so), sim_notes=_notes(se))
    log(f'    simulate rc {rc} {w:.1f} s; {_notes(se)}')
    if rc != 0:
        return row
    rc, so, se, w, c = run_cli(['evaluate', '--pattern', pat.name, *pargs, '--deployed', 'deployed.csv'], d)
    row.update(eval_rc=rc, eval_wall=w, eval_cpu=c, eval=_json(so), eval_notes=_notes(se))
    log(f'    evaluate rc {rc} {w:.1f} s; {so.strip()}')
    if row['eval']:                          # how far the free end (the deployed curve's first node) moved
        dep = np.loadtxt(d / 'deployed.csv', delimiter=',', skiprows=1)
        # an image's stroke has no direction: the perceived pattern may start at either end of the drawn one
        ends = (pts[0], pts[-1]) if fmt == 'png' else (pts[0],)
        row['free_end_moved_m'] = float(min(np.linalg.norm(dep[0] - e) for e in ends))
        if fmt == 'png':                     # Eq. 17 against the points the image was drawn from as well
            from rod_deploy.deployment.metrics import eq17_error
            row['e_mean_vs_drawn_cm'] = eq17_error(pts, dep)['e_mean_cm']
    return row


# ------------------------------------------------------------------------------------------------ bad inputs
def error_cases(shp):
    """(name, pattern file text or None for a good pattern, rod YAML text or None for rod #3, method, expected words
    in the message)."""
    e = shp['letter_e'][0]
    good = ''.join(f'{x:.6f} {y:.6f}\n' for x, y in e)
    rod3 = rod_yaml('rod3', 'L_gb')
    long_line = ''.join(f'{x:.4f} 0.0\n' for x in np.linspace(0, 1.2, 200))
    nan = good.splitlines()
    nan[57] = '0.1 nan'
    rep = good.splitlines()
    rep.insert(101, rep[100])
    tight = ''.join(f'{x:.6f} {y:.6f}\n' for x, y in _arc((0, 0), 0.005, 0, 1.5 * np.pi, 100))
    c = np.array([[0, 0], [0.05, 0.05], [0.1, 0], [0.15, 0.05], [0.2, 0]])
    zig = ''.join(f'{x:.6f} {y:.6f}\n' for x, y in np.vstack([np.linspace(c[i], c[i + 1], 40, endpoint=False)
                                                              for i in range(4)] + [c[-1:]]))
    return [
        ('pattern longer than the rod (1.2 m line, 0.89 m rod)', long_line, None, 'nn', ['longer than the rod']),
        ('2 points', '0 0\n0.1 0\n', None, 'nn', ['at least 3 points']),
        ('empty pattern file', '', None, 'nn', ['at least 3 points, got 0']),
        ('NaN in line 58', '\n'.join(nan) + '\n', None, 'nn', ['not finite', 'line 58']),
        ('a repeated point (line 102)', '\n'.join(rep) + '\n', None, 'nn', ['repeat', 'line 102']),
        ('a 5 mm circle (too sharp)', tight, None, 'nn', ['too sharply']),
        ('zig-zag with sharp corners (161 points)', zig, None, 'nn', ['sharp']),
        ('the heart (cusps)', None, None, 'nn', ['sharp'], 'heart'),
        ('letter e in millimetres', None, None, 'nn', ['longer than the rod'], 'letter_e_mm'),
        ('pattern in the robot frame (z = 0.75)', ''.join(f'{x:.6f} {y:.6f} 0.75\n' for x, y in e), None, 'nn',
         ['z = 0.75', 'line 1']),
        ('decimal commas "0,1 0,2"', '0,1 0,2\n0,2 0,25\n0,3 0,2\n', None, 'nn', ['comma']),
        ('decimal comma that parses as 3 numbers "0,15 0"', '0 0\n0,15 0\n0,3 0\n', None, 'nn',
         ['comma', 'line 2']),
        ('semicolon separators', '0;0\n0,1;0\n0,2;0,1\n', None, 'nn', ['semicolon', 'line 1']),
        ('a word in line 3', '0 0\n0.1 0\nabc 0.2\n0.3 0.1\n', None, 'nn', ['line 3']),
        ('4 numbers on a line', '0 0\n0.1 0 0 1\n0.2 0.1\n', None, 'nn', ['line 2']),
        # the node named must lie at the drawn cusp, (0, 0.08) m (not at the exact node of one planner's spline)
        dict(name='the digit 3 (a cusp in its middle)', pattern=shp['digit3'][0], words=['sharp'],
             near=((0.0, 0.08), 0.005)),
        ('pattern file missing', 'MISSING', None, 'nn', ['does not exist']),
        ('rod: no radius', good, 'length: 0.89\nL_gb: 0.034\n', 'nn', ['radius']),
        ('rod: no L_gb / loop_height / E+rho', good, 'length: 0.89\nradius: 0.002\n', 'nn', ['L_gb']),
        ('rod: youngs_modulus without density', good, 'length: 0.89\nradius: 0.002\nyoungs_modulus: 1e6\n', 'nn',
         ['density']),
        ('rod: negative radius', good, 'length: 0.89\nradius: -0.002\nL_gb: 0.034\n', 'nn', ['radius']),
        ('rod: length as text "0.89 m"', good, 'length: 0.89 m\nradius: 0.002\nL_gb: 0.034\n', 'nn', ['length']),
        ('rod: typo lgb', good, 'length: 0.89\nradius: 0.002\nlgb: 0.034\n', 'nn', ['lgb']),
        ('rod: L_gb in cm (3.4)', good, 'length: 0.89\nradius: 0.002\nL_gb: 3.4\n', 'nn', ['L_gb']),
        ('rod: radius in mm (2), intuitive', good, 'length: 0.89\nradius: 2\nL_gb: 0.034\n', 'intuitive',
         ['radius']),
        ('rod: everything in mm, intuitive', good, 'length: 890\nradius: 2\nL_gb: 34\n', 'intuitive',
         ['length', 'metres']),
        ('rod: friction: yes', good, 'length: 0.89\nradius: 0.002\nL_gb: 0.034\nfriction: yes\n', 'nn',
         ['friction', 'number']),
        ('rod: L_gb and loop_height that disagree', good,
         'length: 0.89\nradius: 0.002\nL_gb: 0.034\nloop_height: 0.05\n', 'nn', ['L_gb', 'loop_height']),
        ('rod: L_gb given twice', good, 'length: 0.89\nradius: 0.002\nL_gb: 0.034\nL_gb: 0.05\n', 'nn',
         ['L_gb', 'twice']),
        ('rod: YAML syntax error', good, 'length: [0.89\nradius: 0.002\n', 'nn', ['not valid YAML']),
        ('rod: not a mapping', good, '- 0.89\n- 0.002\n', 'nn', ['mapping']),
        ('rod: radius 0', good, 'length: 0.89\nradius: 0\nL_gb: 0.034\n', 'nn', ['radius']),
        ('rod: friction -0.3', good, 'length: 0.89\nradius: 0.002\nL_gb: 0.034\nfriction: -0.3\n', 'nn',
         ['friction']),
    ], rod3


def fresh_error_cases(shp):
    """Bad inputs of the fresh set, each of which the contract or issue #10 implies must be refused (as dicts: see
    :func:`do_error_case`); the planner's, the simulator's and the evaluation's."""
    _, mouse_paused = shp['mouse_polyline'][0], shp['mouse_polyline_paused'][0]
    k = int(np.flatnonzero(np.all(np.diff(mouse_paused, axis=0) == 0, axis=1))[0]) + 1   # the first repeated point
    good = shp['digit7'][0]
    good_text = ''.join(f'{x:.6f} {y:.6f}\n' for x, y in good)
    inf = good_text.splitlines()
    inf[30] = 'inf 0.1'
    out_back = np.vstack([np.column_stack([np.linspace(0, 0.1, 41), np.zeros(41)]),
                          np.column_stack([np.linspace(0.1, 0.0, 41)[1:], np.full(40, 0.002)])])
    meander = shp['long_meander_0p855m'][0]
    rod1, rod3 = rod_yaml('rod1', 'L_gb'), rod_yaml('rod3', 'L_gb')
    traj = ('t,x,y,z,qx,qy,qz,qw\n0.0,0.0,0.0,0.9,1.0,0.0,0.0,0.0\n1.0,0.0,0.0,0.89,1.0,0.0,0.0,0.0\n'
            '2.0,0.0,0.01,0.88,1.0,0.0,0.0,0.0\n')
    sim = ['simulate', '--traj', 'traj.csv', '--rod', 'rod.yaml', '--out', 'deployed.csv', '--quiet']
    ev = ['evaluate', '--pattern', 'pattern.txt', '--deployed', 'deployed.csv']
    paper = np.full((300, 300, 3), 245, np.uint8)
    return [
        dict(name='mouse polyline with a pause (4 equal samples)', pattern=mouse_paused,
             words=['repeat', f'line {k + 1}']),
        dict(name='"inf" in line 31', pattern='\n'.join(inf) + '\n',
             words=['not finite', 'line 31']),
        dict(name='a stroke drawn out and back along itself (a 180-degree reversal)', pattern=out_back,
             words=['sharp'], near=((0.1, 0.001), 0.005)),
        dict(name='the 0.855 m meander stretched to 0.872 m, on rod #1 (allows 0.866 m)', pattern=1.02 * meander,
             rod=rod1, words=['longer than the rod']),
        dict(name='rod: no length', rod='radius: 0.002\nL_gb: 0.034\n', words=['length']),
        dict(name='rod: empty file', rod='', words=['rod.yaml']),
        dict(name='rod: loop_height 0', rod='length: 0.89\nradius: 0.002\nloop_height: 0\n', words=['loop_height']),
        dict(name='rod: youngs_modulus .nan', rod='length: 0.89\nradius: 0.002\nyoungs_modulus: .nan\n'
             'density: 1180\n', words=['youngs_modulus']),
        dict(name='rod: negative density', rod='length: 0.89\nradius: 0.002\nyoungs_modulus: 1.0e7\n'
             'density: -1180\n', words=['density']),
        dict(name='rod file missing', rod=None, words=['rod.yaml']),
        dict(name='image without --m-per-px', image=shp['cursive_l_image'][0], words=['--m-per-px']),
        dict(name='image with --m-per-px -0.0005', image=shp['cursive_l_image'][0],
             args=['--m-per-px', '-0.0005'], words=['m-per-px']),
        dict(name='image of blank paper', image=paper, args=['--m-per-px', '0.0005'], words=['pattern.png']),
        dict(name='a text file named pattern.png', image='0 0\n0.1 0\n0.2 0.05\n', args=['--m-per-px', '0.0005'],
             words=['pattern.png']),
        dict(name='simulate: t not strictly increasing', traj=traj.replace('\n2.0,', '\n1.0,'), cmd=sim,
             out='deployed.csv', words=['increasing', 'row 3']),
        dict(name='simulate: a quaternion of norm 2', traj=traj.replace('0.88,1.0,', '0.88,2.0,'), cmd=sim, out='deployed.csv', words=['quaternion']),
        dict(name='simulate: scalar-first header t,x,y,z,qw,qx,qy,qz', traj=traj.replace('qx,qy,qz,qw', 'qw,qx,qy,qz'),
             cmd=sim, out='deployed.csv', words=['header']),
        dict(name='simulate: nan in the trajectory', traj=traj.replace('0.89,1.0', 'nan,1.0'), cmd=sim,
             out='deployed.csv', words=['not finite']),
        dict(name='evaluate: deployed shape with a nan', pattern=good, deployed='x,y\n0,0\n0.1,nan\n0.2,0.1\n',
             cmd=ev, out=None, words=['finite']),
        dict(name='evaluate: deployed shape with one point', pattern=good, deployed='x,y\n0,0\n', cmd=ev, out=None,
             words=['deployed']),
    ], rod3


def _named_point(msg):
    """The first "(x, y) m" point a message names, or None."""
    import re
    m = re.search(r'\((-?[0-9.]+), (-?[0-9.]+)\) m', msg)
    return None if m is None else np.array([float(m.group(1)), float(m.group(2))])


def do_error_case(k, case, shp, rod3, log, folder='errors'):
    """One bad input: a tuple (name, pattern text | None | 'MISSING', rod text | None, method, words[, shape]) of
    ``plan``, or a dict with ``name``, ``words`` (all must be in the message) and any of ``pattern`` (text or points),
    ``image`` (points drawn as a PNG, an image array, or text written to pattern.png), ``rod`` (text; None: no
    file; default rod #3), ``traj``, ``deployed`` (file texts), ``cmd`` (default ``plan``), ``args`` (more
    arguments), ``out`` (the file that must not be written; None: nothing on stdout either), ``near`` ((x, y), tol:
    the point the message names must lie within tol [m] of (x, y))."""
    if isinstance(case, tuple):
        name, pat_text, rod_text, method, words = case[:5]
        case = dict(name=name, words=words, method=method, rod=rod_text if rod_text is not None else rod3,
                    pattern=shp[case[5]][0] if len(case) > 5 else pat_text)
    d = WORK / folder / f'case{k:02d}'
    if d.exists():
        shutil.rmtree(d)
    d.mkdir(parents=True)
    pattern = case.get('pattern', shp['letter_e' if 'letter_e' in shp else 'digit7'][0])
    if 'image' in case:
        img = case['image']
        if isinstance(img, str):
            (d / 'pattern.png').write_text(img)
        elif img.ndim == 3:
            import cv2
            cv2.imwrite(str(d / 'pattern.png'), img)
        else:
            write_png(d / 'pattern.png', img)
        pattern_name = 'pattern.png'
    else:
        pattern_name = 'pattern.txt'
        if isinstance(pattern, str):
            if pattern != 'MISSING':
                (d / pattern_name).write_text(pattern)
        elif pattern is not None:
            write_pattern(d / pattern_name, pattern, 'xy')
    rod_text = case.get('rod', rod3)
    if rod_text is not None:
        (d / 'rod.yaml').write_text(rod_text)
    for key in ('traj', 'deployed'):
        if key in case:
            (d / ('traj.csv' if key == 'traj' else 'deployed.csv')).write_text(case[key])
    cmd = case.get('cmd') or ['plan', '--pattern', pattern_name, '--rod', 'rod.yaml', '--method',
                              case.get('method', 'nn'), '--out', 'traj.csv', '--quiet']
    out = case.get('out', 'traj.csv')
    rc, so, se, w, _ = run_cli([*cmd, *case.get('args', [])], d)
    lines = [ln for ln in se.splitlines() if ln.strip()]
    msg = lines[-1] if lines else ''
    written = (d / out).exists() if out else bool(so.strip())
    near_ok = True
    if 'near' in case:
        p = _named_point(msg)
        near_ok = p is not None and float(np.linalg.norm(p - case['near'][0])) <= case['near'][1]
    ok = (rc == 2 and len(lines) == 1 and 'Traceback' not in se and not written
          and all(wd.lower() in msg.lower() for wd in case['words']) and near_ok)
    log(f'error case {case["name"]}: rc {rc}, {"ok" if ok else "NOT OK"}: {se.strip()[:300]}')
    expected = list(case['words']) + ([f'a point within {1e3 * case["near"][1]:g} mm of '
                                       f'({case["near"][0][0]:g}, {case["near"][0][1]:g}) m'] if 'near' in case else [])
    return {'case': case['name'], 'command': cmd[0], 'rc': rc, 'lines': len(lines), 'traceback': 'Traceback' in se,
            'file_written': written, 'message': msg, 'expected_words': expected, 'ok': ok, 'wall': w}


# ------------------------------------------------------------------------------------------------ report
def _f(v, fmt='.2f'):
    return '-' if v is None else format(v, fmt)


#: the CLI's notes, shortened for the table (the full text is in the .json)
_SHORT = (('rod-deploy plan: note: the friction-limited start', 'plan: start note'),
          ('rod-deploy plan: note: the pattern bends', 'plan: bend note'),
          ('rod-deploy plan: note: the planned curve', 'plan: bend note (planned curve)'),
          ("rod-deploy plan: note: the pattern's points are up to", 'plan: sparse-points note'),
          ("rod-deploy evaluate: note: the pattern's points are up to", 'evaluate: sparse-points note'))


def _short(note):
    for long, short in _SHORT:
        if note.startswith(long):
            return short
    return note.replace('|', '/').replace('rod-deploy plan: ', '')


def _largest_step(row, plan):
    """The largest gripper move between two consecutive poses after the lead-in [cm] (nodes are 5 mm apart on the
    pattern), from the run's trajectory file."""
    f = ROOT / row.get('dir', '') / 'traj.csv'
    if not plan or not f.exists():
        return None
    p = np.loadtxt(f, delimiter=',', skiprows=1)[plan['lead_in_poses']:, 1:4]
    return 100 * float(np.linalg.norm(np.diff(p, axis=0), axis=1).max())


def write_report(out, rows, errs, total_s, elastica=None, shape_set='original', load_end=None):
    """The results table (``out``, .md), its .json and figure; ``load_end``: the 1-min load average when the runs
    ended (default now; a rewrite after replays or added runs keeps the first run's)."""
    load_end = os.getloadavg()[0] if load_end is None else load_end
    lines = ['# Acceptance rehearsal (issue #10), `python benchmarks/acceptance_rehearsal.py'
             + (' --set fresh`' if shape_set == 'fresh' else '`'), '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{load_end:.1f} at the end of the runs); {total_s:.0f} s in all. Each command is its own `rod-deploy` '
             'process, timed from outside (wall clock; CPU in brackets). Shapes drawn by code in the script, '
             'never used to develop or tune anything. Simulation: our DER with the CLI defaults (5 mm edges, dt 0.02 '
             's, 0.01 m/s); friction 0.5 from the rod file. Eq. 17 e_mean / sigma in cm (N = 50, the better '
             'direction). "free end": how far the deployed curve\'s first node lies from the pattern\'s first point. '
             '"start replaced": the friction-limited start (the default) replaces the first cm of the pattern, up to '
             'mm away from it (plan\'s JSON line). kappa_bar: the pattern\'s largest |kappa_bar| / the planned '
             'curve\'s. "gripper step": the largest gripper move between two consecutive poses after the lead-in '
             '(the pattern nodes are 5 mm apart).', '',
             '| shape | rod (form) | method | worked | plan s | simulate s | evaluate s | e_mean cm | sigma cm | '
             'coverage | free end moved cm | start replaced cm / mm | kappa_bar | gripper step cm | notes |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        ev = r.get('eval') or {}
        plan = r.get('plan') or {}
        worked = 'yes' if ev else ('refused' if r['plan_rc'] == 2 else ('planned' if r['plan_rc'] == 0 and
                                                                      'sim_rc' not in r else 'FAILED'))
        notes = '; '.join(_short(n) for n in r.get('plan_notes', []) + r.get('sim_notes', []) + r.get('eval_notes', []))
        repl = (f'{100 * plan["start_replaced_m"]:.0f} / {1000 * plan["start_max_deviation_m"]:.0f}'
                if plan.get('start_replaced_m') else ('0' if 'start_replaced_m' in plan else '-'))
        kb = (f'{plan.get("pattern_max_abs_kappa_bar", plan.get("max_abs_kappa_bar")):.2f} / '
              f'{plan["max_abs_kappa_bar"]:.2f}' if plan else '-')
        lines.append(
            f'| {r["shape"]} | {r["rod"]} ({r["form"]}) | {r["method"]} | {worked} | '
            f'{_f(r.get("plan_wall"), ".1f")} ({_f(r.get("plan_cpu"), ".1f")}) | '
            f'{_f(r.get("sim_wall"), ".0f")} ({_f(r.get("sim_cpu"), ".0f")}) | '
            f'{_f(r.get("eval_wall"), ".1f")} | {_f(ev.get("e_mean_cm"), ".3f")} | {_f(ev.get("sigma_cm"), ".3f")} | '
            f'{_f(ev.get("coverage"), ".2f")} | {_f(100 * r["free_end_moved_m"] if "free_end_moved_m" in r else None)}'
            f' | {repl} | {kb} | {_f(_largest_step(r, plan), ".1f")} | {notes} |')
    walls = [r['plan_wall'] for r in rows]
    if walls:
        lines += ['', f'`rod-deploy plan` (the whole process): {min(walls):.1f}-{max(walls):.1f} s wall, median '
                      f'{np.median(walls):.1f} s ({sum(w > 5 for w in walls)} of {len(walls)} over 5 s); CPU '
                      f'{min(r["plan_cpu"] for r in rows):.1f}-{max(r["plan_cpu"] for r in rows):.1f} s.']
    if elastica:
        st = elastica[0].get('settings') or {}
        lines += ['', '## Independent replay in PyElastica 1.0.0 (`--elastica`, `.venv-bench`)', '',
                  'The same trajectory files replayed by `benchmarks/pyelastica_replay.py`\'s `replay_in_elastica` '
                  + (f'with its defaults (Cosserat rod, {1e3 * st["element_length_m"]:g} mm elements, dt '
                     f'{st["dt_s"]:g} s, friction law `{st["friction_law"]}`, the same hanging start, lead-in and '
                     'release)' if st else '(its settings of the time)')
                  + ', scored with Eq. 17 against the same pattern file; one batch per rod file and replay process '
                  '(CPU: the process\'s CPU time for its batch; load: the 1-min load average when the batch ended). '
                  'Targets of issue #10 (medium friction): e_mean <= 0.2 cm in PyElastica, <= 0.1 cm in our DER.'
                  + (f' Note: {elastica[0]["note"]}.' if elastica[0].get('note') else ''), '',
                  '| run | PyElastica e_mean cm | sigma cm | coverage | our DER e_mean cm | difference cm | '
                  'PyElastica <= 0.2 | element mm / dt s | batch (runs) | CPU s (batch) | load |',
                  '|---|---|---|---|---|---|---|---|---|---|---|']
        ours = {r['dir']: (r.get('eval') or {}).get('e_mean_cm') for r in rows}
        for e in sorted(elastica, key=lambda e: [r['dir'] for r in rows].index(e['dir'])
                        if e['dir'] in ours else len(rows)):
            der = ours.get(e['dir'])
            lines.append(f'| {Path(e["dir"]).name} | {e["e_mean_cm"]:.3f} | {e["sigma_cm"]:.3f} | {e["coverage"]:.2f} | '
                         f'{_f(der, ".3f")} | {_f(None if der is None else e["e_mean_cm"] - der, "+.3f")} | '
                         f'{"yes" if e["e_mean_cm"] <= 0.2 else "no"} | '
                         f'{1e3 * e["settings"]["element_length_m"]:g} / {e["settings"]["dt_s"]:g} | '
                         f'{e.get("batch", "-")} | '
                         f'{_f(e.get("cpu_s"), ".0f")} | {_f(e.get("load"), ".1f")} |')
    lines += summary_against_targets(rows, elastica)
    lines += ['', '## Bad inputs: exit 2, one line naming the problem, no traceback, no file (evaluate: nothing on '
                  'stdout)', '', f'{sum(e["ok"] for e in errs)} of {len(errs)} as expected. "as expected": exit 2, one '
              'line, no traceback, no file, and the expected words (and point) in the message.', '',
              '| case | command | exit | lines | traceback | file | as expected | expected | message |',
              '|---|---|---|---|---|---|---|---|---|']
    for e in errs:
        lines.append(f'| {e["case"]} | {e.get("command", "plan")} | {e["rc"]} | {e["lines"]} | {e["traceback"]} | '
                     f'{e["file_written"]} | {"yes" if e["ok"] else "**no**"} | '
                     f'{"; ".join(e.get("expected_words", [])).replace("|", "/")} | '
                     f'{e["message"].replace("|", "/")[:400]} |')
    try:
        if plot_overview(out.with_suffix('.png'), rows):
            lines.insert(4, f'Overview of the simulated runs: `{out.with_suffix(".png").name}`.\n')
    except Exception as e:                       # noqa: BLE001 - the table matters more than the figure
        print(f'no overview plot: {e}', file=sys.stderr)
    out.write_text('\n'.join(lines) + '\n')
    out.with_suffix('.json').write_text(json.dumps({'runs': rows, 'errors': errs, 'elastica': elastica or [],
                                                    'load_end': load_end}, indent=1, default=str))
    return lines


def summary_against_targets(rows, elastica):
    """Per shape (default plans, the runs without extra arguments): the three methods' e_mean in our DER, nn's in
    PyElastica, the intuitive / nn ratio and the times, against issue #10's targets."""
    shapes = list(dict.fromkeys(r['shape'] for r in rows if r['method'] in ('nn', 'numeric', 'intuitive')))
    el = {e['dir']: e['e_mean_cm'] for e in elastica or []}
    by = {(r['shape'], r['method']): r for r in rows}
    if not shapes:
        return []
    out = ['', '## Against the targets (default plans)', '',
           'Targets of issue #10: e_mean <= 0.1 cm in our DER and <= 0.2 cm in PyElastica (medium friction), nn better '
           'than intuitive on every pattern and >= 3x on the mean; the whole `rod-deploy plan` process <= 5 s; '
           'simulating a 0.9 m rod <= 60 s. Times: wall clock (CPU) of the process, on the shared 2 cores.', '',
           '| shape | rod | nn e_mean cm (DER) | <= 0.1 | nn PyElastica | <= 0.2 | numeric | intuitive | intuitive / nn '
           '| nn plan s | nn simulate s | refused / failed |', '|---|---|---|---|---|---|---|---|---|---|---|---|']
    pairs = []
    for shape in shapes:
        nn, num, it = (by.get((shape, m)) for m in ('nn', 'numeric', 'intuitive'))

        def e(r):
            return ((r or {}).get('eval') or {}).get('e_mean_cm')
        ratio = e(it) / e(nn) if e(nn) and e(it) else None
        if ratio is not None:
            pairs.append((e(nn), e(it)))
        pe = el.get(nn['dir']) if nn else None
        refused = ', '.join(f'{m} ({"refused" if r["plan_rc"] == 2 else "FAILED"})' for m, r in
                            (('nn', nn), ('numeric', num), ('intuitive', it)) if r and r['plan_rc'] != 0)
        out.append(f'| {shape} | {(nn or num or it)["rod"]} | {_f(e(nn), ".3f")} | '
                   f'{"-" if e(nn) is None else ("yes" if e(nn) <= 0.1 else "no")} | {_f(pe, ".3f")} | '
                   f'{"-" if pe is None else ("yes" if pe <= 0.2 else "no")} | {_f(e(num), ".3f")} | '
                   f'{_f(e(it), ".3f")} | {_f(ratio, ".1f")} | '
                   f'{_f((nn or {}).get("plan_wall"), ".1f")} ({_f((nn or {}).get("plan_cpu"), ".1f")}) | '
                   f'{_f((nn or {}).get("sim_wall"), ".0f")} ({_f((nn or {}).get("sim_cpu"), ".0f")}) | {refused or "-"} |')
    if pairs:
        a, b = np.array(pairs).T
        out += ['', f'Shapes simulated with both nn and intuitive: {len(pairs)}; nn mean {a.mean():.3f} cm, intuitive '
                    f'mean {b.mean():.3f} cm ({b.mean() / a.mean():.1f}x); nn better on {int(np.sum(a < b))} of '
                    f'{len(pairs)} (least ratio {np.min(b / a):.1f}x); nn within 0.1 cm on {int(np.sum(a <= 0.1))} '
                    f'of {len(pairs)}.']
    return out


def plot_overview(path, rows):
    """One panel per simulated run: the pattern, our DER's deployed curve (and PyElastica's when replayed); False
    (nothing written) without a simulated run."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    sims = [r for r in rows if r.get('eval')]
    if not sims:
        return False
    cols = 6
    fig, axs = plt.subplots((len(sims) + cols - 1) // cols, cols, figsize=(3.2 * cols, 3.0 * ((len(sims) + cols - 1)
                                                                                          // cols)), squeeze=False)
    for ax in axs.ravel()[len(sims):]:
        ax.axis('off')
    for ax, r in zip(axs.ravel(), sims):
        d = ROOT / r['dir']
        pat = load_run_pattern(d)
        dep = np.loadtxt(d / 'deployed.csv', delimiter=',', skiprows=1)
        ax.plot(*pat.T, '-', color='0.6', lw=3, alpha=0.6)
        ax.plot(*pat[0], 'ko', ms=3)
        ax.plot(*dep.T, '-', color='tab:blue', lw=1)
        ax.plot(*dep[0], 'o', color='tab:blue', ms=3)
        if (d / 'deployed_elastica.csv').exists():
            el = np.loadtxt(d / 'deployed_elastica.csv', delimiter=',', skiprows=1, ndmin=2)
            ax.plot(*el.T, '--', color='tab:orange', lw=1)
        ax.set_aspect('equal', adjustable='datalim')
        ax.set_title(f'{r["shape"]}, {r["rod"]}, {r["method"]}\ne_mean {r["eval"]["e_mean_cm"]:.2f} cm', fontsize=7)
        ax.tick_params(labelsize=6)
    fig.suptitle('grey: pattern (dot: first point); blue: deployed, our DER (dot: free end); orange dashed: '
                 'PyElastica', fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=70)
    plt.close(fig)
    from PIL import Image                        # a small file: 64 colours are enough for lines on white
    Image.open(path).convert('RGB').quantize(64).save(path, optimize=True)
    return True


def replay_elastica(run_dirs, log, element_m=None, dt_s=None):
    """Replay the runs' trajectories in PyElastica, one batch per rod file (run in .venv-bench); ``element_m``,
    ``dt_s``: PyElastica's element length and step instead of ``ElasticaSettings``' defaults (the project's replays
    use 2.5 mm elements for rod #1 and dt 1.2e-4 s for rod #2)."""
    from dataclasses import asdict, replace

    from pyelastica_replay import ElasticaSettings, replay_in_elastica
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.planning.rod_description import load_rod_description
    from rod_deploy.planning.trajectory_io import read_trajectory_csv
    el_settings = ElasticaSettings()
    if element_m is not None:
        el_settings = replace(el_settings, element_length_m=element_m)
    if dt_s is not None:
        el_settings = replace(el_settings, dt_s=dt_s)
    settings = {k: v for k, v in asdict(el_settings).items()
                if k in ('element_length_m', 'dt_s', 'friction_law', 'applied_normal')}
    batches = {}
    for d in run_dirs:                       # one batch per rod (its three forms of file are the same rod)
        d = ROOT / d
        r = load_rod_description(d / 'rod.yaml')
        key = tuple(round(v, 6) for v in (r.length_m, r.radius_m, r.gravito_bending_length_m, r.friction or 0.5))
        batches.setdefault(key, []).append(d)
    out = []
    for _, dirs in batches.items():
        rod = load_rod_description(dirs[0] / 'rod.yaml')
        cases = [(*read_trajectory_csv(d / 'traj.csv'), None) for d in dirs]
        log(f'PyElastica: {len(dirs)} trajectories of {dirs[0].name} ...')
        cpu = time.process_time()
        res, wall = replay_in_elastica(cases, rod, rod.friction if rod.friction is not None else 0.5, el_settings)
        cpu = time.process_time() - cpu
        for d, r in zip(dirs, res):
            np.savetxt(d / 'deployed_elastica.csv', r['deployed_xy'], delimiter=',', header='x,y', comments='')
            e = eq17_error(load_run_pattern(d), r['deployed_xy'])
            out.append({'dir': str(d.relative_to(ROOT)), 'wall_s': wall, 'cpu_s': cpu, 'batch': len(dirs),
                        'load': os.getloadavg()[0], 'settings': settings, **e})
            log(f'    {d.name}: e_mean {e["e_mean_cm"]:.3f} cm')
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--only', default='', help='comma-separated shapes (default: all runs)')
    ap.add_argument('--no-sim', action='store_true', help='plan only')
    ap.add_argument('--jobs', type=int, default=1, help='runs at once (each run is three processes in turn; the '
                    'times are per process, CPU from wait4)')
    ap.add_argument('--errors-only', action='store_true')
    ap.add_argument('--no-errors', action='store_true')
    ap.add_argument('--elastica', nargs='+', metavar='RUN_DIR',
                    help='replay these runs\' trajectories (out/acceptance/...) in PyElastica and add them to the '
                         'results of the last run (run with .venv-bench/bin/python, PYTHONPATH=ros_ws/src/rod_deploy)')
    ap.add_argument('--merge-after', metavar='FILE',
                    help='--elastica: wait for FILE to exist before adding the results (replays started while the '
                         'rehearsal itself, which rewrites the results, is still running)')
    ap.add_argument('--elastica-element', type=float, help='--elastica: element length [m] (default: '
                    'pyelastica_replay.ElasticaSettings)')
    ap.add_argument('--elastica-dt', type=float, help='--elastica: time step [s] (default: ElasticaSettings)')
    ap.add_argument('--report-only', action='store_true', help='rewrite the table (and figure) from the last run\'s json')
    ap.add_argument('--set', choices=('original', 'fresh'), default='original',
                    help='original: the shapes of rounds 1-8 (looked at while developing since); fresh: the second set '
                         '(round 9), every method on each, its own bad inputs; run files under out/acceptance/fresh/')
    ap.add_argument('--methods', help='comma-separated methods to run (default: every run of the set)')
    ap.add_argument('--plan-args', default='', help='more arguments for every `rod-deploy plan` (e.g. "--start '
                    'tangent": what the default start costs or gains on the shapes it refuses or lays far off)')
    ap.add_argument('--add-runs', action='store_true',
                    help='add the runs to the last results of the set (replacing runs of the same folder), keeping '
                         'its bad inputs and PyElastica replays (implies --no-errors)')
    ap.add_argument('--results-name', help='results file name (default acceptance_rehearsal.md, or '
                    'acceptance_rehearsal_fresh.md with --set fresh)')
    add_results_argument(ap)
    args = ap.parse_args()
    global WORK
    fresh = args.set == 'fresh'
    shp = fresh_shapes() if fresh else shapes()
    if fresh:
        WORK = WORK / 'fresh'
    if args.no_sim:           # a folder of its own: a plan-only run would delete the simulated runs' files
        WORK = WORK / 'plan_only'
    WORK.mkdir(parents=True, exist_ok=True)
    t_all = time.perf_counter()

    def log(msg):
        print(msg, flush=True)

    out = results_path(args, args.results_name or ('acceptance_rehearsal_fresh.md' if fresh else
                                                   'acceptance_rehearsal.md'))
    if args.elastica or args.report_only:
        new = replay_elastica(args.elastica, log, args.elastica_element, args.elastica_dt) if args.elastica else []
        while args.merge_after and not Path(args.merge_after).exists():     # the rehearsal itself still running
            time.sleep(10)
        # several replay processes may run at once on disjoint runs: each merges its rows into the last run's
        # results under a lock (a run replayed again replaces its row)
        with open(out.with_suffix('.lock'), 'w') as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            previous = json.loads(out.with_suffix('.json').read_text())
            replayed = {e['dir'] for e in new}
            el = [e for e in previous.get('elastica') or [] if e['dir'] not in replayed] + new
            write_report(out, previous['runs'], previous['errors'], previous.get('total_s', 0.0), el,
                         shape_set=args.set, load_end=previous.get('load_end'))
            data = json.loads(out.with_suffix('.json').read_text())
            out.with_suffix('.json').write_text(json.dumps({**data, 'total_s': previous.get('total_s', 0.0)},
                                                           indent=1, default=str))
        print(f'wrote {out}')
        return

    rows = []
    if not args.errors_only:
        more = tuple(args.plan_args.split())
        todo = [(shape, rod, form, method, sim and not args.no_sim, shp, log, *extra) if not more else
                (shape, rod, form, method, sim and not args.no_sim, shp, log, (*(extra[0] if extra else ()), *more))
                for shape, rod, form, method, sim, *extra in (FRESH_RUNS if fresh else RUNS)
                if (not args.only or shape in args.only.split(','))
                and (not args.methods or method in args.methods.split(','))]
        with ThreadPoolExecutor(max_workers=args.jobs) as pool:       # each run is its own processes
            rows = list(pool.map(lambda a: do_run(*a), todo))
    errs = []
    if args.add_runs:
        with open(out.with_suffix('.lock'), 'w') as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            previous = json.loads(out.with_suffix('.json').read_text())
            added = {r['dir'] for r in rows}
            rows = [r for r in previous['runs'] if r['dir'] not in added] + rows
            write_report(out, rows, previous['errors'], previous.get('total_s', 0.0) + time.perf_counter() - t_all,
                         previous.get('elastica'), shape_set=args.set, load_end=previous.get('load_end'))
            data = json.loads(out.with_suffix('.json').read_text())
            out.with_suffix('.json').write_text(json.dumps(
                {**data, 'total_s': previous.get('total_s', 0.0) + time.perf_counter() - t_all}, indent=1,
                default=str))
        print(f'added {len(added)} runs to {out}')
        return
    if not args.no_errors:
        cases, rod3 = fresh_error_cases(shp) if fresh else error_cases(shp)
        errs = [do_error_case(k, c, shp, rod3, log) for k, c in enumerate(cases)]
    total = time.perf_counter() - t_all
    write_report(out, rows, errs, total, shape_set=args.set)
    data = json.loads(out.with_suffix('.json').read_text())
    out.with_suffix('.json').write_text(json.dumps({**data, 'total_s': total}, indent=1, default=str))
    print(f'wrote {out}')


if __name__ == '__main__':
    main()
