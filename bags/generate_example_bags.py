#!/usr/bin/env python3
"""Regenerate the shipped example recordings: Baxter's right arm handling a clamped flexible loop (MuJoCo).

    .venv/bin/python bags/generate_example_bags.py [--only example_loop12] [--no-plots]

Each bags/<example>/ is self-contained:
  experiment.yaml         the experiment (CONTRACTS.md section 2); its urdf path points at the copy beside it
  baxter_right_arm.urdf   copy of ros_ws/src/flex_ident/flex_ident/data/baxter_right_arm.urdf
  bag/                    rosbag2 (MCAP): /joint_states of the 7 arm joints at 100 Hz (CONTRACTS.md section 1)
  truth.json, truth.npz   the simulator's settings and true (noise-free) arm and loop states
  overview.png            joint angles, efforts and loop angles over time
The simulator is robot_bridge.sim.mujoco_loop, independent of flex_ident's model. Existing outputs are replaced.
"""
from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from robot_bridge.bagio.contract import write_joint_recording
from robot_bridge.sim.motion import SumOfSinesMotion
from robot_bridge.sim.mujoco_loop import simulate_loop_experiment, save_truth

HERE = Path(__file__).resolve().parent
URDF = HERE.parent / 'ros_ws' / 'src' / 'flex_ident' / 'flex_ident' / 'data' / 'baxter_right_arm.urdf'

# Gripper pointing straight down, holding the top of a vertical loop whose bottom is clamped 2R lower
# (the paper's Fig. 1 set-up): C = (0.6, -0.8, -0.3) m, z_C down, loop plane turned 135 deg about the vertical.
CLAMP = {'xyz': [0.6, -0.8, -0.3], 'rpy': [float(np.pi), 0.0, float(0.75 * np.pi)]}
NOISE = {'position_rad': 2e-4, 'velocity_rad_s': 5e-3, 'effort_nm': 0.1}
TRUTH = {'k_theta': 5.0, 'k_phi': 3.0}

EXAMPLES = {
    'example_loop12': {'links': 12, 'duration_s': 20.0, 'amplitude_scale': 1.0, 'seed': 12},
    'example_loop6': {'links': 6, 'duration_s': 10.0, 'amplitude_scale': 0.6, 'seed': 6},
}


def experiment_yaml(links: int) -> dict:
    """The contract experiment; no `window`: the whole recording is used (samples at 0 .. duration - 0.01 s)."""
    return {
        'arm': {'urdf': 'baxter_right_arm.urdf', 'base_link': 'base', 'tip_link': 'right_gripper',
                'joints': ['right_s0', 'right_s1', 'right_e0', 'right_e1', 'right_w0', 'right_w1', 'right_w2']},
        'object': {'type': 'loop', 'links': links, 'radius': 0.25, 'mass': 0.6, 'tube_radius': 0.02,
                   'grasp': {'xyz': [0.0, 0.0, 0.0], 'rpy': [0.0, 0.0, 0.0]}, 'clamp': CLAMP},
        'identify': {'parameters': {'k_theta': {'initial': 1.0, 'min': 0.001, 'max': 1000.0},
                                    'k_phi': {'initial': 1.0, 'min': 0.001, 'max': 1000.0}}},
    }


def overview_plot(path: Path, rec, title: str):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(3, 1, figsize=(9, 7.5), sharex=True)
    ax[0].plot(rec.t_s, rec.position - rec.position[0])
    ax[0].set_ylabel('q - q(0) [rad]')
    ax[0].legend(rec.names, ncol=4, fontsize=7, loc='upper right')
    ax[1].plot(rec.t_s, rec.effort)
    ax[1].set_ylabel('effort [N m]')
    ax[2].plot(rec.t_s, rec.loop_position, lw=0.8)
    ax[2].set_ylabel('loop angles [rad] (truth)')
    ax[2].set_xlabel('t [s]')
    ax[0].set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=60)
    plt.close(fig)


def generate(name: str, spec: dict, plots: bool = True) -> float:
    t0 = time.perf_counter()
    folder = HERE / name
    folder.mkdir(exist_ok=True)
    for stale in ('bag', 'truth.json', 'truth.npz', 'overview.png'):
        target = folder / stale
        if target.is_dir():
            shutil.rmtree(target)
        elif target.exists():
            target.unlink()
    shutil.copyfile(URDF, folder / 'baxter_right_arm.urdf')
    exp_path = folder / 'experiment.yaml'
    header = (f'# {name}: Baxter right arm handling a clamped {spec["links"]}-link flexible loop (simulated in MuJoCo\n'
              f'# by bags/generate_example_bags.py; true k_theta = {TRUTH["k_theta"]}, k_phi = {TRUTH["k_phi"]} '
              'N m/rad, see bags/README.md).\n')
    exp_path.write_text(header + yaml.safe_dump(experiment_yaml(spec['links']),
                                                sort_keys=False, default_flow_style=None))
    default = SumOfSinesMotion()
    motion = SumOfSinesMotion(amplitudes_rad=tuple(spec['amplitude_scale'] * np.asarray(default.amplitudes_rad)))
    rec = simulate_loop_experiment(exp_path, spec['duration_s'], seed=spec['seed'], noise=NOISE, motion=motion,
                                   **TRUTH)
    write_joint_recording(folder / 'bag', rec.joint_recording(), storage='mcap')
    save_truth(folder / 'truth', rec)
    if plots:
        overview_plot(folder / 'overview.png', rec,
                      f'{name}: k_theta={TRUTH["k_theta"]}, k_phi={TRUTH["k_phi"]} N m/rad (simulated)')
    wall = time.perf_counter() - t0
    size = sum(f.stat().st_size for f in (folder / 'bag').rglob('*') if f.is_file())
    i = rec.info
    print(f'{name}: {len(rec.t_s)} samples, bag {size / 1e6:.2f} MB, settled in {i["settle_time_s"]:.2f} s, '
          f'max weld residual {i["max_weld_residual_m"]:.1e} m / {i["max_weld_residual_rad"]:.1e} rad, '
          f'{i["saturated_steps"]} saturated steps, {wall:.1f} s')
    return wall


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--only', choices=sorted(EXAMPLES), action='append', help='regenerate just these')
    parser.add_argument('--no-plots', action='store_true')
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    for name in args.only or EXAMPLES:
        generate(name, EXAMPLES[name], plots=not args.no_plots)
    print(f'total {time.perf_counter() - t0:.1f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
