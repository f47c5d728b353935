"""`make demo`: both flows of the product as one ROS graph, on the shipped defaults, in this process.

All nodes are composed in one process on a MultiThreadedExecutor (what a launch file starts on a full ROS install):

1. Identification: bag_player (fake hardware) replays the example experiment's bag on /joint_states;
   joint_state_logger records it and, when the replay has ended, closes the bag and announces it on
   /joint_state_logger/recorded; stiffness_identifier identifies it with the closed loop (diagnose: on, passed
   explicitly) and publishes /identification/result.
2. Deployment: the drawn pattern image shipped in the repository goes out on /deploy_request; pattern_perception ->
   /pattern -> grasp_trajectory_generator -> /gripper_trajectory -> arm_command_bridge (IK) ->
   /arm_controller/joint_trajectory -> sim_arm (MuJoCo Baxter) -> /joint_states; deployment_monitor lays the rod
   along the gripper path the arm executed (forward kinematics of the measured joints), publishes /deploy_result,
   /deployed_shape and /deploy_markers.
A recorder (another joint_state_logger) writes every topic of the demo to an MCAP bag that Foxglove opens.

Writes out/ (overwritten each run): report.json, deployment.json, the plots (cost_vs_iteration.png,
end_effector_path.png, residual_over_time.png, deployment.png), perception_overlay.png, recording/ (MCAP of the
demo's topics), identification/ and deployment/ (everything the nodes saved). Prints a summary.
``--quick``: the 6-link example and a coarse, fast rod simulation (2 cm edges, the gripper path replayed at
0.1 m/s: the free end is dragged, e_mean is about a centimetre; for the test).
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
os.environ.setdefault('MPLBACKEND', 'Agg')

PATTERN_IMAGE = ROOT / 'ros_ws/src/rod_deploy/rod_deploy/data/drawn_pattern.png'
M_PER_PX = 0.0005                  # the shipped image's scale (scripts/make_drawn_pattern.py)
ROD = {'length': 0.5, 'radius': 0.002, 'L_gb': 0.034}     # the paper's rod #3 material, 0.5 m long
RECORDED_TOPICS = ['/joint_states', '/deploy_request', '/pattern', '/gripper_trajectory',
                   '/arm_controller/joint_trajectory', '/deployed_shape', '/deploy_result', '/deploy_markers',
                   '/pattern_perception/status', '/grasp_trajectory_generator/status', '/arm_command_bridge/status',
                   '/identification/status', '/identification/result', '/identification/markers',
                   '/joint_state_logger/recorded']
IDENTIFICATION_PLOTS = ['cost_vs_iteration.png', 'end_effector_path.png', 'residual_over_time.png']


def step(title):
    print(f'\n=== {title}', flush=True)


def fail(message) -> int:
    print(f'demo: error: {message}', file=sys.stderr)
    return 1


def wait(predicate, timeout_s, what, every_s=10.0, status=None):
    """Poll ``predicate`` (printing ``status()`` every ``every_s``); False after ``timeout_s``."""
    t0 = last = time.monotonic()
    while not predicate():
        now = time.monotonic()
        if now - t0 > timeout_s:
            print(f'  timed out after {timeout_s:.0f} s waiting for {what}', flush=True)
            return False
        if status is not None and now - last >= every_s:
            print(f'  ... {what}: {status()} ({now - t0:.0f} s)', flush=True)
            last = now
        time.sleep(0.05)
    return True


def image_message(path: Path):
    import cv2
    from sensor_msgs.msg import Image
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise ValueError(f'cannot read the pattern image {path}')
    h, w = bgr.shape[:2]
    return Image(height=h, width=w, encoding='bgr8', step=3 * w, data=bgr.tobytes()), bgr


def perception_overlay(bgr, out: Path):
    """The overlay of what perception sees in the request image (the node publishes the path; the picture is
    drawn here with the same pipeline)."""
    import cv2
    from rod_deploy.perception.overlay import draw_overlay
    from rod_deploy.perception.pipeline import PerceptionConfig, perceive
    result = perceive(bgr, PerceptionConfig(step_px=2.0))
    cv2.imwrite(str(out), draw_overlay(bgr, result.objects, result.crossings, M_PER_PX))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--example', default=None, help='example folder with bag/ and experiment.yaml '
                    '(default: bags/example_loop12; --quick: bags/example_loop6)')
    ap.add_argument('--image', default=str(PATTERN_IMAGE), help='drawn pattern image (0.5 mm per pixel)')
    ap.add_argument('--out', default=str(ROOT / 'out'))
    ap.add_argument('--rate', type=float, default=5.0, help='bag replay speed factor')
    ap.add_argument('--quick', action='store_true', help='the 6-link example and a coarse rod simulation')
    args = ap.parse_args(argv)
    example = Path(args.example or ROOT / 'bags' / ('example_loop6' if args.quick else 'example_loop12'))
    out = Path(args.out)
    for needed in (example / 'bag', example / 'experiment.yaml', Path(args.image)):
        if not needed.exists():
            return fail(f'{needed} not found')
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)

    import rclpy
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    from flex_ident.nodes.joint_state_logger import JointStateLogger
    from flex_ident.nodes.stiffness_identifier import StiffnessIdentifier
    from robot_bridge.nodes.arm_command_bridge import ArmCommandBridge
    from robot_bridge.nodes.bag_player import BagPlayer
    from robot_bridge.nodes.sim_arm import SimArm
    from rod_deploy.nodes.deployment_monitor import DeploymentMonitor
    from rod_deploy.nodes.grasp_trajectory_generator import GraspTrajectoryGenerator
    from rod_deploy.nodes.pattern_perception import PatternPerception

    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    t_start = time.monotonic()
    rclpy.init()
    executor = MultiThreadedExecutor(num_threads=6)
    nodes = []

    def add(node):
        nodes.append(node)
        executor.add_node(node)
        return node

    spin = threading.Thread(target=executor.spin, daemon=True)
    spin.start()
    try:
        client = add(Node('demo_client'))
        results = {}
        client.create_subscription(String, '/identification/result',
                                   lambda m: results.setdefault('identification', json.loads(m.data)), latched)
        client.create_subscription(String, '/deploy_result',
                                   lambda m: results.setdefault('deployment', json.loads(m.data)), latched)
        recorder = add(JointStateLogger(cli_args=['--ros-args', '-r', '__node:=demo_recorder'], parameter_overrides=[
            Parameter('output', value=str(out / 'recording')), Parameter('topics', value=RECORDED_TOPICS)]))

        step(f'1. identification graph: bag_player ({example.name}, x{args.rate:g}) -> /joint_states -> '
             f'joint_state_logger -> bag -> stiffness_identifier (closed loop on)')
        add(StiffnessIdentifier(parameter_overrides=[
            Parameter('experiment', value=str(example / 'experiment.yaml')),
            Parameter('out', value=str(out / 'identification')), Parameter('diagnose', value=True),
            Parameter('recorded_topic', value='/joint_state_logger/recorded')]))
        logger = add(JointStateLogger(parameter_overrides=[
            Parameter('output', value=str(out / 'identification_recording')),
            Parameter('topics', value=['/joint_states']), Parameter('close_after_idle_s', value=1.0)]))
        player = add(BagPlayer(parameter_overrides=[Parameter('bag', value=str(example / 'bag')),
                                                    Parameter('rate', value=args.rate)]))
        if not wait(logger.closed.is_set, 120, 'the replay to be recorded',
                    status=lambda: f'{player.published} messages replayed'):
            return fail('the replay was not recorded')
        print(f'  recorded {dict(logger.counts)} -> {out / "identification_recording"}; identifying '
              f'(in the identifier\'s worker thread) while the deployment runs')
        executor.remove_node(player)
        player.close()

        step('2. deployment graph: drawn pattern on /deploy_request -> pattern_perception -> '
             'grasp_trajectory_generator -> arm_command_bridge -> sim_arm; deployment_monitor')
        rod = [Parameter(k, value=v) for k, v in ROD.items()]
        coarse = [Parameter('edge_length_m', value=0.02), Parameter('dt_s', value=0.05),
                  Parameter('max_gripper_speed_m_s', value=0.1)]
        fine = [Parameter('edge_length_m', value=0.01), Parameter('dt_s', value=0.05),
                Parameter('max_gripper_speed_m_s', value=0.02)]
        sim = add(SimArm(parameter_overrides=[Parameter('real_time_factor', value=5.0)]))
        bridge = add(ArmCommandBridge())
        add(PatternPerception(parameter_overrides=[Parameter('m_per_px', value=M_PER_PX)]))
        add(GraspTrajectoryGenerator(parameter_overrides=rod + [Parameter('speed_m_s', value=0.05)]))
        monitor = add(DeploymentMonitor(parameter_overrides=rod + (coarse if args.quick else fine) + [
            Parameter('out', value=str(out / 'deployment'))]))
        request_pub = client.create_publisher(type(image_message(Path(args.image))[0]), '/deploy_request',
                                              QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
        if not wait(lambda: bridge.current_q is not None and request_pub.get_subscription_count() > 0, 30,
                    'the simulated arm'):
            return fail('the simulated arm did not come up')
        msg, bgr = image_message(Path(args.image))
        perception_overlay(bgr, out / 'perception_overlay.png')
        t_request = time.monotonic()
        request_pub.publish(msg)
        print(f'  published {Path(args.image).name} ({msg.width} x {msg.height} px) on /deploy_request')
        if wait(lambda: 'deployment' in results or (
                sim.commands_received and (monitor._request or {}).get('stage') != 'execution'), 300,
                'the arm to execute the trajectory', status=lambda: f'arm at {sim.sim_time_s:.1f} s simulated'):
            executor.remove_node(sim)       # the arm's part is done: free the CPU for the rod and the identification
            sim.close()
            print(f'  the arm executed the trajectory ({sim.sim_time_s:.1f} s simulated); laying the rod along it')
        if not wait(lambda: 'deployment' in results, 600, 'the deployment result',
                    status=lambda: f'stage {(monitor._request or {}).get("stage", "done")}'):
            return fail('no deployment result')
        deployment = results['deployment']
        if 'error' in deployment:
            return fail(f'the deployment request failed at {deployment["stage"]}: {deployment["error"]}')
        print(f'  deployed in {time.monotonic() - t_request:.1f} s: e_mean {deployment["e_mean_cm"]:.3f} cm, '
              f'sigma {deployment["sigma_cm"]:.3f} cm')

        step('3. waiting for the identification report')
        if not wait(lambda: 'identification' in results, 600, 'the identification result',
                    status=lambda: 'identifying'):
            return fail('no identification result')
        report = results['identification']
        if 'error' in report:
            return fail(f'the identification failed: {report["error"]}')
        time.sleep(0.5)                  # the recorder's last messages
        recorder.close()
    finally:
        executor.shutdown()
        spin.join(timeout=5)
        for node in nodes:
            if hasattr(node, 'close'):
                node.close()
            node.destroy_node()
        rclpy.try_shutdown()
    return summarise(out, example, report, deployment, recorder.counts, time.monotonic() - t_start)


def summarise(out: Path, example: Path, report: dict, deployment: dict, recorded: dict, wall_s: float) -> int:
    shutil.copy(out / 'identification' / 'report.json', out / 'report.json')
    for name in IDENTIFICATION_PLOTS:
        if (out / 'identification' / name).exists():
            shutil.copy(out / 'identification' / name, out / name)
    shutil.copy(deployment['files']['json'], out / 'deployment.json')
    shutil.copy(deployment['files']['plot'], out / 'deployment.png')
    step(f'summary ({wall_s:.0f} s; everything in {out})')
    truth_file = example / 'truth.json'
    truth = json.loads(truth_file.read_text()) if truth_file.exists() else {}
    for name, value in report['parameters'].items():
        true = _find(truth, name)
        versus = f' (simulator truth {true:g}: {100 * (value - true) / true:+.2f} %)' if true else ''
        print(f'  identified {name} = {value:.4f}{versus}')
    effects = [e['name'] for e in report.get('effects_added', [])]
    print(f"  closed loop: {', '.join(effects) if effects else 'no missing effect found'}; end-effector RMS "
          f"{1e3 * report['error_before']['ee_rms_m']:.2f} mm (initial guess) -> "
          f"{1e3 * report['error_after']['ee_rms_m']:.3f} mm; {report['wall_time_s']:.1f} s")
    t = deployment['timings_s']
    tr = deployment['tracking']
    print(f"  deployment: e_mean {deployment['e_mean_cm']:.3f} cm, sigma {deployment['sigma_cm']:.3f} cm, coverage "
          f"{deployment['coverage']:.2f}; executed gripper path within {tr['executed_vs_planned_max_mm']:.3f} mm of "
          f"the plan; request to result {t['total']:.1f} s (rod simulation {t['rod_simulation']:.1f} s)")
    print(f"  recording: {out / 'recording'} (MCAP, {sum(recorded.values())} messages on {len(recorded)} topics)")
    print('  files: report.json, deployment.json, ' + ', '.join(
        p.name for p in sorted(out.glob('*.png'))))
    return 0


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
