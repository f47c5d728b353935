"""Are the reported parameter_std of a loop recording calibrated? One MuJoCo experiment (the 6-link example loop,
true k = (5, 3), the contract's noise), recorded again and again with new measurement-noise seeds (the motion is the
same), each identified with the default command (closed loop on). For each parameter: the fraction of runs whose
truth lies within +-2 reported std (about 95 % when calibrated), for the reported (HAC, Newey-West) std and for the
curvature std sigma^2 (J^T J)^-1 kept beside it; the spread of the estimates over the seeds against the mean
reported std; the mean error (a bias the noise cannot explain: the variational integrator is not MuJoCo).

    python benchmarks/closed_loop_calibration.py [--seeds 20] [--duration 6] [--commit-results]

Writes closed_loop_calibration.md / .json (out/benchmarks/, or benchmarks/results/ with --commit-results).
"""
import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_dir import add_results_argument, results_path  # noqa: E402

from flex_ident.identification.identify import IdentificationSettings, identify  # noqa: E402
from robot_bridge.bagio.contract import write_joint_recording  # noqa: E402
from robot_bridge.sim.mujoco_loop import (MeasurementNoise, SumOfSinesMotion,  # noqa: E402
                                          simulate_loop_experiment)

REPO = Path(__file__).resolve().parents[1]
EXPERIMENT = REPO / 'bags' / 'example_loop6' / 'experiment.yaml'
TRUTH = {'k_theta': 5.0, 'k_phi': 3.0}
NOISE = MeasurementNoise(position_rad=2e-4, velocity_rad_s=5e-3, effort_nm=0.1)


def run_seed(seed: int, duration_s: float, work: Path) -> dict:
    motion = SumOfSinesMotion(amplitudes_rad=tuple(0.6 * np.asarray(SumOfSinesMotion().amplitudes_rad)))
    rec = simulate_loop_experiment(EXPERIMENT, duration_s, k_theta=TRUTH['k_theta'], k_phi=TRUTH['k_phi'], seed=seed,
                                   noise=NOISE, motion=motion)
    bag = work / f'seed{seed}'
    write_joint_recording(bag, rec.joint_recording())
    t0 = time.monotonic()
    report = identify(bag, EXPERIMENT, work / f'out{seed}', IdentificationSettings(plots=False)).report
    return {'seed': seed, 'parameters': report['parameters'], 'std': report['parameter_std'],
            'std_curvature': report['parameter_std_curvature'], 'effects_added': [e['key'] for e in
                                                                                  report['effects_added']],
            'note': report['parameter_std_note'], 'wall_time_s': time.monotonic() - t0}


def summary(rows) -> dict:
    out = {}
    for name, truth in TRUTH.items():
        est = np.array([r['parameters'][name] for r in rows])
        std = np.array([r['std'][name] for r in rows])
        curv = np.array([r['std_curvature'][name] for r in rows])
        out[name] = {'truth': truth, 'mean': float(est.mean()), 'mean_error_pct': float(100 * (est.mean() / truth - 1)),
                     'spread_std': float(est.std(ddof=1)), 'mean_reported_std': float(std.mean()),
                     'mean_curvature_std': float(curv.mean()),
                     'covered_hac': float(np.mean(np.abs(est - truth) <= 2 * std)),
                     'covered_curvature': float(np.mean(np.abs(est - truth) <= 2 * curv)),
                     'spread_covered_hac': float(np.mean(np.abs(est - est.mean()) <= 2 * std))}
    return out


def markdown(rows, s, args, wall_s) -> str:
    lines = [f'# Calibration of parameter_std on loop recordings ({len(rows)} noise seeds)', '',
             f'`python benchmarks/closed_loop_calibration.py --seeds {args.seeds} --duration {args.duration:g}'
             f'{" --commit-results" if args.commit_results else ""}` ({wall_s / 60:.0f} min on the shared 2-core '
             f'machine). MuJoCo, 6-link example loop, {args.duration:g} s at 100 Hz, true k = (5, 3), noise 2e-4 rad, '
             '5e-3 rad/s, 0.1 N m; one motion, new noise each seed; default command (closed loop on).', '',
             '| parameter | mean (truth) | mean error % | spread of the estimates (std over seeds) | mean reported '
             'std (HAC) | truth within +-2 HAC std | truth within +-2 curvature std (mean std) | mean within +-2 HAC '
             'std |', '|---|---|---|---|---|---|---|---|']
    for name, v in s.items():
        lines.append(f'| {name} | {v["mean"]:.4f} ({v["truth"]:g}) | {v["mean_error_pct"]:+.3f} | '
                     f'{v["spread_std"]:.4f} '
                     f'| {v["mean_reported_std"]:.4f} | {100 * v["covered_hac"]:.0f} % | '
                     f'{100 * v["covered_curvature"]:.0f} % ({v["mean_curvature_std"]:.4f}) | '
                     f'{100 * v["spread_covered_hac"]:.0f} % |')
    invented = [r['seed'] for r in rows if r['effects_added']]
    lines += ['', f'Effects added on these clean recordings: {"none" if not invented else invented}. '
              'The last column measures the std against the spread of the estimates alone (the mean over seeds '
              'in place of the truth), that is the noise part of the error without the simulator mismatch.', '',
              '| seed | k_theta | std | k_phi | std | s |', '|---|---|---|---|---|---|']
    for r in rows:
        lines.append(f'| {r["seed"]} | {r["parameters"]["k_theta"]:.4f} | {r["std"]["k_theta"]:.4f} | '
                     f'{r["parameters"]["k_phi"]:.4f} | {r["std"]["k_phi"]:.4f} | {r["wall_time_s"]:.0f} |')
    return '\n'.join(lines) + '\n'


def main():
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--seeds', type=int, default=20)
    p.add_argument('--duration', type=float, default=6.0)
    add_results_argument(p)
    args = p.parse_args()
    t0 = time.monotonic()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(args.seeds):
            rows.append(run_seed(seed, args.duration, Path(tmp)))
            left = (time.monotonic() - t0) / len(rows) * (args.seeds - len(rows))
            print(json.dumps(rows[-1], default=str), f'(about {left / 60:.0f} min left)', flush=True)
    s = summary(rows)
    wall = time.monotonic() - t0
    results_path(args, 'closed_loop_calibration.json').write_text(json.dumps({'summary': s, 'runs': rows}, indent=1))
    md = markdown(rows, s, args, wall)
    results_path(args, 'closed_loop_calibration.md').write_text(md)
    print(md)


if __name__ == '__main__':
    main()
