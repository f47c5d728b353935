"""The closed loop on real arm logs (``../shared/data/robot_torque``, read in place): `flex-ident identify` with an
arm-only experiment on the Franka Panda, KUKA LWR4+ and Kinova Gen3 logs; validation torque RMS (last 30 %, never
fitted) before and after, the effects named, the time; and the Franka friction we find against the friction Gaz et
al. published for the same robot (plot).

    python benchmarks/closed_loop_real.py [--commit-results]

The Schunk arm is skipped: its kinematic and dynamic parameters are not shipped with the data (they are in Liu &
Althoff 2018, which we could not retrieve here), so no URDF exists for it.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from results_dir import add_results_argument, results_path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / 'shared' / 'data' / 'robot_torque'
BIN = Path(sys.executable).parent
ROBOTS = {
    'Franka Panda (21 s, 1 kHz)': ('franka_panda_gaz2019/panda_exciting_traj1.csv', 'franka_gaz2019',
                                   'franka_panda_gaz2019/panda_gaz2019.urdf', 'panda_link0', 'panda_link8',
                                   [f'panda_joint{i}' for i in range(1, 8)]),
    'KUKA LWR4+ (25 s, 200 Hz, placeholder 2 kg masses)': (
        'kuka_lwr4_flobaroid/kuka_lwr4_measurements_1.csv', 'kuka_lwr4', 'kuka_lwr4_flobaroid/kuka_lwr4.urdf',
        'lwr_base_link', 'lwr_7_link', [f'lwr_{i}_joint' for i in range(7)]),
    'Kinova Gen3 (2 s, 1 kHz)': ('kinova_gen3_chiha2024/RunTrajectory1.csv', 'kinova_gen3',
                                 'kinova_gen3_chiha2024/gen3.urdf', 'base_link', 'end_effector_link',
                                 [f'joint_{i}' for i in range(1, 8)]),
}


def gaz_friction(v, phi1, phi2, phi3):
    return phi1 / (1 + np.exp(-phi2 * (v + phi3))) - phi1 / (1 + np.exp(-phi2 * phi3))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    add_results_argument(ap)
    args = ap.parse_args()
    if not DATA.exists():
        sys.exit(f'{DATA} not present: this benchmark reads the shared real logs in place')
    work = ROOT / 'out' / 'closed_loop_real'
    work.mkdir(parents=True, exist_ok=True)
    out = results_path(args, 'closed_loop_real.md')
    lines = ['# The closed loop on real arm logs (`python benchmarks/closed_loop_real.py`)', '',
             f'Machine: {platform.machine()}, {os.cpu_count()} cores. Default command `flex-ident identify --bag B '
             '--experiment E --out D` on an arm-only experiment (URDF, base and tip link, joints). Torque RMS over '
             'all joints on the validation part (the last 30 % of the recording, never fitted), N m.', '',
             '| robot | nominal | after | factor | effects named (in order) | warnings | time s |',
             '|---|---|---|---|---|---|---|']
    reports = {}
    for name, (csv, preset, urdf, base, tip, joints) in ROBOTS.items():
        tag = preset
        bag = work / f'{tag}_bag'
        if not bag.exists():
            subprocess.run([str(BIN / 'bag-tools'), 'import-csv', str(DATA / csv), '--out', str(bag), '--preset',
                            preset], check=True, capture_output=True)
        exp = work / f'{tag}.yaml'
        exp.write_text(f'arm:\n  urdf: {DATA / urdf}\n  base_link: {base}\n  tip_link: {tip}\n  joints: {joints}\n')
        t0 = time.perf_counter()
        proc = subprocess.run([str(BIN / 'flex-ident'), 'identify', '--bag', str(bag), '--experiment', str(exp),
                               '--out', str(work / tag), '--quiet'], capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            lines.append(f'| {name} | failed: {proc.stderr.strip()[:120]} | | | | | {wall:.1f} |')
            continue
        r = json.loads((work / tag / 'report.json').read_text())
        reports[tag] = r
        b, a = r['error_before']['torque_rms_nm'], r['error_after']['torque_rms_nm']
        effects = '; '.join(e['name'] for e in r['effects_added']) or 'none'
        warn = ' '.join(r.get('warnings', []))[:160]
        lines.append(f'| {name} | {b:.3f} | {a:.3f} | x{b / a:.2f} | {effects} | {warn} | {wall:.1f} |')
        print(lines[-1], flush=True)
    if 'franka_gaz2019' in reports:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
        r = reports['franka_gaz2019']
        params = {}
        for e in r['effects_added']:
            params.update(e['parameters'])
        table = np.genfromtxt(DATA / 'franka_panda_gaz2019' / 'identified_friction_gaz2019.csv', delimiter=',',
                              names=True, skip_header=2)
        v = np.linspace(-1.5, 1.5, 301)
        fig, axes = plt.subplots(2, 4, figsize=(13, 5.6))
        rows = ['', '| joint | ours at +1 rad/s | Gaz 2019 at +1 rad/s | ours at -1 rad/s | Gaz 2019 at -1 rad/s |',
                '|---|---|---|---|---|']
        for j in range(7):
            jn = f'panda_joint{j + 1}'
            ours = (params.get(f'f_coulomb_{jn}_nm', params.get('f_coulomb_nm', 0.0)) * np.tanh(v / 0.02)
                    + params.get(f'b_viscous_{jn}_nms_per_rad', params.get('b_viscous_nms_per_rad', 0.0)) * v
                    + params.get(f'offset_{jn}_nm', 0.0))
            gaz = gaz_friction(v, table['phi1'][j], table['phi2'][j], table['phi3'][j])
            ax = axes.flat[j]
            ax.plot(v, gaz, 'k--', label='Gaz et al. 2019 (published)')
            ax.plot(v, ours, 'tab:red', label='ours (friction + offset)')
            ax.set_title(jn, fontsize=9)
            ax.set_xlabel('velocity [rad/s]', fontsize=8)
            ax.grid(alpha=0.3)
            i1, i0 = np.searchsorted(v, 1.0), np.searchsorted(v, -1.0)
            rows.append(f'| {jn} | {ours[i1]:.3f} | {gaz[i1]:.3f} | {ours[i0]:.3f} | {gaz[i0]:.3f} |')
        axes.flat[0].set_ylabel('friction torque [N m]')
        axes.flat[0].legend(fontsize=7)
        axes.flat[7].axis('off')
        fig.suptitle('Franka Panda joint friction: found by our closed loop vs published', fontsize=10)
        fig.tight_layout()
        fig.savefig(out.parent / 'closed_loop_real_franka_friction.png', dpi=100)
        plt.close(fig)
        lines += ['', 'Franka friction (ours: the Coulomb/viscous terms and the torque offset the closed loop added; '
                  'Gaz et al.: their sigmoid model, whose value at zero velocity is zero by construction, so an '
                  'offset shows up on both sides):'] + rows + ['', '![friction](closed_loop_real_franka_friction.png)']
    lines += ['', 'Schunk 6-DOF: skipped (no kinematic/dynamic description is shipped with the data).']
    out.write_text('\n'.join(lines) + '\n')
    print(f'results: {out}')


if __name__ == '__main__':
    main()
