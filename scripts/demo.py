"""`make demo`: the main job on the shipped example data, end to end.

1. Fake hardware replays the shipped example bag (bag_player) while joint_state_logger records it,
   both nodes in this process (a launch file would do this on a full ROS install).
2. The recording is summarised (bag-tools info) and checked message by message against the original.
3. flex-ident identifies the loop's spring constants from the recording (report.json + plots) and compares them
   with the simulator's truth.
4. The closed loop: MuJoCo records the small example loop with joint damping the model does not declare;
   flex-ident identify (the closed loop is on by default) finds it, identifies it with the springs and reports the
   error before and after.
5. rod-deploy perceives a drawn pattern (a synthetic pen stroke of known centreline) into an ordered path in metres.
6. rod-deploy solves the optimal grasp at the published test point (ls_bar 13.68, ks_bar 2087, kappa_bar 0.1).
7. rod-deploy plans, from an image of a drawn circle, the gripper trajectory that lays the paper's rod #3 along it
   (neural controller, Alg. 4) and the intuitive baseline's, simulates both deployments in our DER and scores them
   (Eq. 17) (``--quick``: plans only).
Outputs go to demo_out/ (overwritten each run).
"""
import argparse
import json
import os
import random
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 100)))
os.environ.setdefault('ROS_LOG_DIR', tempfile.mkdtemp(prefix='ros_log_'))


def step(title):
    print(f'\n=== {title}', flush=True)


def record_replay(bag: Path, out: Path, rate: float) -> int:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from flex_ident.nodes.joint_state_logger import JointStateLogger
    from robot_bridge.nodes.bag_player import BagPlayer

    rclpy.init()
    executor = SingleThreadedExecutor()
    try:
        logger = JointStateLogger(parameter_overrides=[Parameter('output', value=str(out))])
        player = BagPlayer(parameter_overrides=[Parameter('bag', value=str(bag)), Parameter('rate', value=rate)])
        executor.add_node(logger)
        executor.add_node(player)
        spin = threading.Thread(target=executor.spin, daemon=True)
        spin.start()
        t0 = time.monotonic()
        while not player.done.wait(1.0):
            print(f'  replaying: {player.published} messages, {time.monotonic() - t0:.0f} s', flush=True)
        deadline = time.monotonic() + 5
        while sum(logger.counts.values()) < player.published and time.monotonic() < deadline:
            time.sleep(0.05)
        logger.close()
        return player.exit_code
    finally:
        executor.shutdown()
        rclpy.try_shutdown()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--example', default=str(ROOT / 'bags' / 'example_loop12'),
                    help='example folder with bag/ and experiment.yaml')
    ap.add_argument('--out', default=str(ROOT / 'demo_out'))
    ap.add_argument('--rate', type=float, default=5.0, help='replay speed factor')
    ap.add_argument('--quick', action='store_true', help='step 7 plans but does not simulate the deployments')
    args = ap.parse_args()
    from robot_bridge.bagio.raw import iter_raw_messages
    from robot_bridge.cli import bag_tools

    example, out = Path(args.example), Path(args.out)
    bag = example / 'bag'
    if not bag.exists():
        print(f'demo: error: example bag {bag} not found', file=sys.stderr)
        return 1
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)

    step(f'1. replay {bag.relative_to(ROOT)} (x{args.rate}) through bag_player -> joint_state_logger')
    if record_replay(bag, out / 'recording', args.rate) != 0:
        return 1
    step(f'2. what the logger recorded (bag-tools info; replayed at x{args.rate:g}, so the receive times span '
         f'1/{args.rate:g} of the header stamps)')
    bag_tools.main(['info', str(out / 'recording')])
    original = [m.data for m in iter_raw_messages(bag, topics=['/joint_states'])]
    recorded = [m.data for m in iter_raw_messages(out / 'recording', topics=['/joint_states'])]
    print(f'  /joint_states: {len(recorded)} of {len(original)} messages recorded, '
          f"byte-identical: {'yes' if original == recorded else 'NO'}")
    if original != recorded:
        return 1

    step('3. stiffness identification from the recording (flex-ident identify)')
    from flex_ident.cli.main import main as flex_ident_main
    status = flex_ident_main(['identify', '--bag', str(out / 'recording'),
                              '--experiment', str(example / 'experiment.yaml'), '--out', str(out / 'identification')])
    if status != 0:
        return status
    report = json.loads((out / 'identification' / 'report.json').read_text())
    truth_file = example / 'truth.json'
    truth = json.loads(truth_file.read_text()) if truth_file.exists() else {}
    for name, value in report['parameters'].items():
        true = _find(truth, name)
        versus = f'  (simulator truth {true:g}: {100 * (value - true) / true:+.2f} %)' if true else ''
        print(f"  {name} = {value:.4f} +- {report['parameter_std'].get(name, float('nan')):.4f}{versus}")
    print(f"  end-effector RMS error: {1000 * report['error_before']['ee_rms_m']:.2f} mm at the initial guess -> "
          f"{1000 * report['error_after']['ee_rms_m']:.3f} mm identified; {report['iterations']} iterations, "
          f"{report['wall_time_s']:.1f} s")
    print(f"  report and plots: {out / 'identification'}")

    step('4. the closed loop: a recording with an effect nobody declared (flex-ident identify, on by default)')
    from robot_bridge.bagio.contract import write_joint_recording
    from robot_bridge.sim.mujoco_loop import Effects, MeasurementNoise, simulate_loop_experiment
    small = ROOT / 'bags' / 'example_loop6'
    print('  MuJoCo: the 6-link example loop with viscous damping 0.05 N m s/rad in its joints (not in the model)')
    rec = simulate_loop_experiment(small / 'experiment.yaml', 10.0, k_theta=5.0, k_phi=3.0, seed=1,
                                   noise=MeasurementNoise(2e-4, 5e-3, 0.1), effects=Effects(loop_damping_nms=0.05))
    write_joint_recording(out / 'damped_recording', rec.joint_recording())
    status = flex_ident_main(['identify', '--bag', str(out / 'damped_recording'), '--experiment',
                              str(small / 'experiment.yaml'), '--out', str(out / 'diagnosis'),
                              '--quiet', '--no-plots'])
    if status != 0:
        return status
    report = json.loads((out / 'diagnosis' / 'report.json').read_text())
    for effect in report['effects_added']:
        values = ', '.join(f'{k} = {v:.4g}' for k, v in effect['parameters'].items())
        print(f"  found: {effect['name']} ({values}; simulator truth 0.05); end-effector RMS "
              f"{1000 * effect['error_before']['ee_rms_m']:.3f} -> {1000 * effect['error_after']['ee_rms_m']:.3f} mm")
    if not report['effects_added']:
        print('  found: no missing effect')
    print(f"  k_theta = {report['parameters']['k_theta']:.4f}, k_phi = {report['parameters']['k_phi']:.4f} "
          f"(truth 5, 3); report: {out / 'diagnosis' / 'report.json'}")

    step('5. perception of a drawn pattern (rod-deploy perceive)')
    import cv2
    import numpy as np
    from rod_deploy.cli.main import main as rod_deploy_main
    from rod_deploy.perception.synthetic import draw_strokes, example_curves
    drawn = example_curves(600)['sine']
    image = draw_strokes((600, 600), [drawn], [6.0], [(40, 40, 40)], gradient=0.25, noise_std=3.0, blur_sigma=0.8)
    cv2.imwrite(str(out / 'drawn_pattern.png'), image)
    status = rod_deploy_main(['perceive', '--image', str(out / 'drawn_pattern.png'), '--m-per-px', '0.0005',
                              '--out', str(out / 'path.csv'), '--overlay', str(out / 'overlay.png'),
                              '--pattern', str(out / 'pattern.txt')])
    if status != 0:
        return status
    path = np.loadtxt(out / 'path.csv', delimiter=',', skiprows=1)
    from scipy.spatial import cKDTree
    dist, _ = cKDTree(drawn).query(path[:, 1:3])
    print(f'  {int(path[:, 0].max()) + 1} object(s), {len(path)} points; centreline vs the drawn curve: '
          f'{np.sqrt(np.mean(dist ** 2)):.2f} px RMS')
    print(f"  path.csv, pattern.txt (metres) and overlay.png in {out}")

    step('6. optimal grasp for the published test point (rod-deploy grasp)')
    status = rod_deploy_main(['grasp', '--ls', '13.68', '--ks', '2087', '--kappa', '0.1'])
    if status != 0:
        return status

    step('7. lay a rod along a drawn circle (rod-deploy plan / simulate / evaluate, from the image)')
    image = draw_strokes((600, 600), [example_curves(600)['circle']], [6.0], [(40, 40, 40)], gradient=0.25,
                         noise_std=3.0, blur_sigma=0.8)
    cv2.imwrite(str(out / 'drawn_circle.png'), image)
    (out / 'rod.yaml').write_text('length: 0.89\nradius: 0.002\nL_gb: 0.034\nfriction: 0.5\n')
    for method in ('nn', 'intuitive'):
        status = rod_deploy_main(['plan', '--pattern', str(out / 'drawn_circle.png'), '--m-per-px', '0.0005',
                                  '--rod', str(out / 'rod.yaml'),
                                  '--method', method, '--out', str(out / f'traj_{method}.csv'),
                                  '--plot', str(out / f'plan_{method}.png')])
        if status != 0 or args.quick:
            continue
        status = rod_deploy_main(['simulate', '--traj', str(out / f'traj_{method}.csv'), '--rod', str(out / 'rod.yaml'),
                                  '--out', str(out / f'deployed_{method}.csv'), '--edge-length', '0.01',
                                  '--plot', str(out / f'deployed_{method}.png'), '--quiet'])
        if status != 0:
            return status
        status = rod_deploy_main(['evaluate', '--pattern', str(out / 'drawn_circle.png'), '--m-per-px', '0.0005',
                                  '--deployed', str(out / f'deployed_{method}.csv')])
    return status


def _find(tree, key):
    """The first number stored under ``key`` anywhere in a nested dict (truth files nest settings)."""
    if isinstance(tree, dict):
        if isinstance(tree.get(key), (int, float)):
            return float(tree[key])
        for value in tree.values():
            found = _find(value, key)
            if found is not None:
                return found
    return None


if __name__ == '__main__':
    sys.exit(main())
