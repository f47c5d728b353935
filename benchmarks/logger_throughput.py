"""Benchmark: joint_state_logger records a 1 kHz /joint_states stream for 60 s without loss (in-process).

bag_player replays a generated 60 s, 1 kHz bag (7 joints, positions/velocities/efforts) in real time to
joint_state_logger in the same process (MultiThreadedExecutor), reliable QoS. Reports messages published,
recorded, dropped, byte equality, and the achieved publish rate. Usage:
    python benchmarks/logger_throughput.py [--seconds 60] [--rate-hz 1000] [--storage mcap] [--executor single]
    python benchmarks/logger_throughput.py --all [--commit-results]    # the README's three rows, results table
"""
import argparse
import os
import platform
import random
import tempfile
import threading
import time

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 100)))
os.environ.setdefault('ROS_LOG_DIR', tempfile.mkdtemp())

import numpy as np  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from flex_ident.nodes.joint_state_logger import JointStateLogger  # noqa: E402
from results_dir import add_results_argument, results_path  # noqa: E402
from robot_bridge.bagio.contract import JointRecording, write_joint_recording  # noqa: E402
from robot_bridge.bagio.raw import iter_raw_messages  # noqa: E402
from robot_bridge.nodes.bag_player import BagPlayer  # noqa: E402


def make_executor(kind):
    return SingleThreadedExecutor() if kind == 'single' else MultiThreadedExecutor(num_threads=4)


def run(seconds, rate_hz, storage, executor_kind):
    tmp = tempfile.mkdtemp()
    n = int(seconds * rate_hz)
    rng = np.random.default_rng(0)
    rec = JointRecording(np.arange(n) / rate_hz, [f'joint_{i}' for i in range(1, 8)],
                         rng.normal(size=(n, 7)), rng.normal(size=(n, 7)), rng.normal(size=(n, 7)),
                         stamp0_ns=1_700_000_000_000_000_000)
    write_joint_recording(f'{tmp}/in', rec, storage=storage)
    rclpy.init()
    executor = make_executor(executor_kind)
    logger = JointStateLogger(parameter_overrides=[
        Parameter('output', value=f'{tmp}/out'), Parameter('storage', value=storage),
        Parameter('topics', value=['/joint_states'])])
    executor.add_node(logger)
    spin = threading.Thread(target=executor.spin, daemon=True)
    spin.start()
    t0 = time.monotonic()
    player = BagPlayer(parameter_overrides=[Parameter('bag', value=f'{tmp}/in'),
                                            Parameter('wait_for_subscribers', value=30.0)])
    executor.add_node(player)
    player.done.wait()
    elapsed = time.monotonic() - t0
    deadline = time.monotonic() + 10
    while logger.counts['/joint_states'] < player.published and time.monotonic() < deadline:
        time.sleep(0.05)
    logger.close()
    executor.shutdown()
    rclpy.try_shutdown()
    original = [m.data for m in iter_raw_messages(f'{tmp}/in')]
    recorded = [m.data for m in iter_raw_messages(f'{tmp}/out')]
    row = dict(executor=executor_kind, storage=storage, seconds=seconds, rate_hz=rate_hz,
               published=player.published, recorded=len(recorded), dropped=len(original) - len(recorded),
               byte_equal=original == recorded, wall_s=elapsed)
    print(f'executor={executor_kind} storage={storage} duration={seconds:.0f} s rate={rate_hz:.0f} Hz')
    print(f'published={row["published"]} recorded={row["recorded"]} dropped={row["dropped"]} '
          f'byte_equal={row["byte_equal"]}')
    print(f'wall time for playback incl. discovery: {elapsed:.2f} s '
          f'(achieved {player.published / elapsed:.0f} msg/s)', flush=True)
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--seconds', type=float, default=60.0)
    ap.add_argument('--rate-hz', type=float, default=1000.0)
    ap.add_argument('--storage', default='mcap')
    ap.add_argument('--executor', default='single', choices=['single', 'multi'],
                    help="'single' is what the node's own main() spins")
    ap.add_argument('--all', action='store_true',
                    help='the three configurations of the README table (MCAP/sqlite3 single, MCAP multi)')
    add_results_argument(ap)
    args = ap.parse_args()
    configs = ([('mcap', 'single'), ('sqlite3', 'single'), ('mcap', 'multi')] if args.all
               else [(args.storage, args.executor)])
    rows = [run(args.seconds, args.rate_hz, storage, kind) for storage, kind in configs]
    lines = ['# Logger throughput (`python benchmarks/logger_throughput.py --all`)', '',
             f'Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; in-process '
             f'bag_player -> joint_state_logger, 7 joints, reliable QoS.', '',
             '| storage | executor | duration | rate | published | recorded | dropped | byte-identical | wall time |',
             '|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        lines.append(f'| {r["storage"]} | {r["executor"]} | {r["seconds"]:.0f} s | {r["rate_hz"]:.0f} Hz | '
                     f'{r["published"]} | {r["recorded"]} | {r["dropped"]} | {"yes" if r["byte_equal"] else "NO"} | '
                     f'{r["wall_s"]:.1f} s |')
    results = results_path(args, 'logger_throughput.md')
    results.write_text('\n'.join(lines) + '\n')
    print(f'results: {results}')
    return 0 if all(r['byte_equal'] for r in rows) else 1


if __name__ == '__main__':
    raise SystemExit(main())
