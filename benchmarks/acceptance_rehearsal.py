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
from scipy.interpolate import splev, splprep

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / 'out' / 'acceptance'
G = 9.81
LOOP = 0.9066

# ------------------------------------------------------------------------------------------------ rods
RODS = {'rod2': dict(length=0.885, radius=0.0016, L_gb=0.032, density=1180.0),
        'rod3': dict(length=0.89, radius=0.002, L_gb=0.034, density=1180.0),
        'cable': dict(length=2.0, radius=0.003, youngs_modulus=1.0e7, density=1400.0)}


def rod_yaml(name, form):
    """The rod ``name`` in the contract's form ``L_gb``, ``loop_height`` or ``E_rho``, with friction 0.5."""
    r = RODS[name]
    h = r['radius']
    if 'L_gb' in r:
        lgb = r['L_gb']
        E = 8.0 * r['density'] * G * lgb ** 3 / h ** 2
    else:
        E = r['youngs_modulus']
        lgb = (E * h ** 2 / (8.0 * r['density'] * G)) ** (1.0 / 3.0)
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


def write_pattern(path, xy, fmt):
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
    pat = d / ('pattern.csv' if fmt == 'csv' else 'pattern.txt')
    write_pattern(pat, pts, fmt)
    (d / 'rod.yaml').write_text(rod_yaml(rod, form))
    row = {'shape': shape, 'rod': rod, 'form': form, 'method': method + ''.join(f' {a}' for a in extra),
           'dir': str(d.relative_to(ROOT))}
    for f in ('traj.csv', 'deployed.csv', 'deployed.png', 'plan.png'):
        (d / f).unlink(missing_ok=True)
    rc, so, se, w, c = run_cli(['plan', '--pattern', pat.name, '--rod', 'rod.yaml', '--method', method, '--out',
                                'traj.csv', '--plot', 'plan.png', '--quiet', *extra], d)
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
    rc, so, se, w, c = run_cli(['evaluate', '--pattern', pat.name, '--deployed', 'deployed.csv'], d)
    row.update(eval_rc=rc, eval_wall=w, eval_cpu=c, eval=_json(so), eval_notes=_notes(se))
    log(f'    evaluate rc {rc} {w:.1f} s; {so.strip()}')
    if row['eval']:                          # how far the free end (the deployed curve's first node) moved
        dep = np.loadtxt(d / 'deployed.csv', delimiter=',', skiprows=1)
        row['free_end_moved_m'] = float(np.linalg.norm(dep[0] - pts[0]))
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
        ('the digit 3 (a cusp in its middle)', None, None, 'nn', ['sharp', '(0.0016, 0.0801)'], 'digit3'),
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


def do_error_case(k, case, shp, rod3, log):
    name, pat_text, rod_text, method, words = case[:5]
    d = WORK / 'errors' / f'case{k:02d}'
    if d.exists():
        shutil.rmtree(d)
    d.mkdir(parents=True)
    if len(case) > 5:
        write_pattern(d / 'pattern.txt', shp[case[5]][0], 'xy')
    elif pat_text != 'MISSING':
        (d / 'pattern.txt').write_text(pat_text)
    (d / 'rod.yaml').write_text(rod_text if rod_text is not None else rod3)
    rc, so, se, w, _ = run_cli(['plan', '--pattern', 'pattern.txt', '--rod', 'rod.yaml', '--method', method,
                                '--out', 'traj.csv', '--quiet'], d)
    lines = [ln for ln in se.splitlines() if ln.strip()]
    msg = lines[-1] if lines else ''
    ok = (rc == 2 and len(lines) == 1 and 'Traceback' not in se and not (d / 'traj.csv').exists()
          and all(wd.lower() in msg.lower() for wd in words))
    log(f'error case {name}: rc {rc}, {"ok" if ok else "NOT OK"}: {se.strip()[:300]}')
    return {'case': name, 'rc': rc, 'lines': len(lines), 'traceback': 'Traceback' in se,
            'file_written': (d / 'traj.csv').exists(), 'message': msg, 'expected_words': words, 'ok': ok,
            'wall': w}


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


def write_report(out, rows, errs, total_s, elastica=None):
    lines = ['# Acceptance rehearsal (issue #10), `python benchmarks/acceptance_rehearsal.py`', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores shared with other jobs (load average '
             f'{os.getloadavg()[0]:.1f} at the end); {total_s:.0f} s in all. Each command is its own `rod-deploy` '
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
                  'PyElastica <= 0.2 | batch (runs) | CPU s (batch) | load |',
                  '|---|---|---|---|---|---|---|---|---|---|']
        ours = {r['dir']: (r.get('eval') or {}).get('e_mean_cm') for r in rows}
        for e in sorted(elastica, key=lambda e: [r['dir'] for r in rows].index(e['dir'])
                        if e['dir'] in ours else len(rows)):
            der = ours.get(e['dir'])
            lines.append(f'| {Path(e["dir"]).name} | {e["e_mean_cm"]:.3f} | {e["sigma_cm"]:.3f} | {e["coverage"]:.2f} | '
                         f'{_f(der, ".3f")} | {_f(None if der is None else e["e_mean_cm"] - der, "+.3f")} | '
                         f'{"yes" if e["e_mean_cm"] <= 0.2 else "no"} | {e.get("batch", "-")} | '
                         f'{_f(e.get("cpu_s"), ".0f")} | {_f(e.get("load"), ".1f")} |')
    lines += ['', '## Bad inputs (`rod-deploy plan`): exit 2, one line naming the problem, no traceback, no file', '',
              '| case | exit | lines | traceback | file | as expected | message |', '|---|---|---|---|---|---|---|']
    for e in errs:
        lines.append(f'| {e["case"]} | {e["rc"]} | {e["lines"]} | {e["traceback"]} | {e["file_written"]} | '
                     f'{"yes" if e["ok"] else "**no**"} | {e["message"].replace("|", "/")[:400]} |')
    try:
        plot_overview(out.with_suffix('.png'), rows)
        lines.insert(4, f'Overview of the simulated runs: `{out.with_suffix(".png").name}`.\n')
    except Exception as e:                       # noqa: BLE001 - the table matters more than the figure
        print(f'no overview plot: {e}', file=sys.stderr)
    out.write_text('\n'.join(lines) + '\n')
    out.with_suffix('.json').write_text(json.dumps({'runs': rows, 'errors': errs, 'elastica': elastica or []},
                                                   indent=1, default=str))
    return lines


def plot_overview(path, rows):
    """One panel per simulated run: the pattern, our DER's deployed curve (and PyElastica's when replayed)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from rod_deploy.planning.pattern_input import load_pattern
    sims = [r for r in rows if r.get('eval')]
    if not sims:
        return
    cols = 6
    fig, axs = plt.subplots((len(sims) + cols - 1) // cols, cols, figsize=(3.2 * cols, 3.0 * ((len(sims) + cols - 1)
                                                                                          // cols)), squeeze=False)
    for ax in axs.ravel()[len(sims):]:
        ax.axis('off')
    for ax, r in zip(axs.ravel(), sims):
        d = ROOT / r['dir']
        pat = load_pattern(d / 'pattern.csv' if (d / 'pattern.csv').exists() else d / 'pattern.txt')
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
    fig.savefig(path, dpi=80)
    plt.close(fig)


def replay_elastica(run_dirs, log):
    """Replay the runs' trajectories in PyElastica, one batch per rod file (run in .venv-bench)."""
    from dataclasses import asdict

    from pyelastica_replay import ElasticaSettings, replay_in_elastica
    from rod_deploy.deployment.metrics import eq17_error
    from rod_deploy.planning.pattern_input import load_pattern
    from rod_deploy.planning.rod_description import load_rod_description
    from rod_deploy.planning.trajectory_io import read_trajectory_csv
    settings = {k: v for k, v in asdict(ElasticaSettings()).items()
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
        res, wall = replay_in_elastica(cases, rod, rod.friction if rod.friction is not None else 0.5)
        cpu = time.process_time() - cpu
        for d, r in zip(dirs, res):
            pf = d / 'pattern.csv' if (d / 'pattern.csv').exists() else d / 'pattern.txt'
            e = eq17_error(load_pattern(pf), r['deployed_xy'])
            out.append({'dir': str(d.relative_to(ROOT)), 'wall_s': wall, 'cpu_s': cpu, 'batch': len(dirs),
                        'load': os.getloadavg()[0], 'settings': settings, **e})
            np.savetxt(d / 'deployed_elastica.csv', r['deployed_xy'], delimiter=',', header='x,y', comments='')
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
    ap.add_argument('--report-only', action='store_true', help='rewrite the table (and figure) from the last run\'s json')
    add_results_argument(ap)
    args = ap.parse_args()
    shp = shapes()
    WORK.mkdir(parents=True, exist_ok=True)
    t_all = time.perf_counter()

    def log(msg):
        print(msg, flush=True)

    out = results_path(args, 'acceptance_rehearsal.md')
    if args.elastica or args.report_only:
        new = replay_elastica(args.elastica, log) if args.elastica else []
        while args.merge_after and not Path(args.merge_after).exists():     # the rehearsal itself still running
            time.sleep(10)
        # several replay processes may run at once on disjoint runs: each merges its rows into the last run's
        # results under a lock (a run replayed again replaces its row)
        with open(out.with_suffix('.lock'), 'w') as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            previous = json.loads(out.with_suffix('.json').read_text())
            replayed = {e['dir'] for e in new}
            el = [e for e in previous.get('elastica') or [] if e['dir'] not in replayed] + new
            write_report(out, previous['runs'], previous['errors'], previous.get('total_s', 0.0), el)
            data = json.loads(out.with_suffix('.json').read_text())
            out.with_suffix('.json').write_text(json.dumps({**data, 'total_s': previous.get('total_s', 0.0)},
                                                           indent=1, default=str))
        print(f'wrote {out}')
        return

    rows = []
    if not args.errors_only:
        todo = [(shape, rod, form, method, sim and not args.no_sim, shp, log, *extra)
                for shape, rod, form, method, sim, *extra in RUNS if not args.only or shape in args.only.split(',')]
        with ThreadPoolExecutor(max_workers=args.jobs) as pool:       # each run is its own processes
            rows = list(pool.map(lambda a: do_run(*a), todo))
    errs = []
    if not args.no_errors:
        cases, rod3 = error_cases(shp)
        errs = [do_error_case(k, c, shp, rod3, log) for k, c in enumerate(cases)]
    total = time.perf_counter() - t_all
    write_report(out, rows, errs, total)
    data = json.loads(out.with_suffix('.json').read_text())
    out.with_suffix('.json').write_text(json.dumps({**data, 'total_s': total}, indent=1, default=str))
    print(f'wrote {out}')


if __name__ == '__main__':
    main()
