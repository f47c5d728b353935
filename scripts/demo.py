"""`make demo`: the main job on the shipped example data, end to end.

1. Fake hardware replays the shipped example bag (bag_player) while joint_state_logger records it,
   both nodes in this process (a launch file would do this on a full ROS install).
2. The recording is summarised (bag-tools info) and checked message by message against the original.
Outputs go to demo_out/ (overwritten each run).
"""
import argparse
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
    step('2. what the logger recorded (bag-tools info)')
    bag_tools.main(['info', str(out / 'recording')])
    original = [m.data for m in iter_raw_messages(bag, topics=['/joint_states'])]
    recorded = [m.data for m in iter_raw_messages(out / 'recording', topics=['/joint_states'])]
    print(f'  /joint_states: {len(recorded)} of {len(original)} messages recorded, '
          f"byte-identical: {'yes' if original == recorded else 'NO'}")
    if original != recorded:
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
