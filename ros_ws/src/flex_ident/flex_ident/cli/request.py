"""`flex-ident request`: send one identification request to a running ``stiffness_identifier`` node and print
its result (the report JSON), as a ROS user would with ``ros2 topic pub`` and ``ros2 topic echo``.

The request carries a fresh ``request_id`` that the node echoes, so an older latched result is never mistaken for
this one. Progress (``/identification/status``) is printed on stderr.
"""
from __future__ import annotations

import json
import sys
import time
import uuid
from pathlib import Path

REQUEST_WAIT_S = 10.0


class RequestFailed(ValueError):
    """No node answered, or the node reported an error for this request."""


def send_request(bag, experiment, out=None, method=None, diagnose=None, timeout_s=600.0, progress=None,
                 discovery_timeout_s=REQUEST_WAIT_S) -> dict:
    """Publish a request on /identification/request and wait for the matching /identification/result.

    Paths are made absolute (the node may run in another working directory). Returns the report dict; raises
    :class:`RequestFailed` when no node subscribes within ``discovery_timeout_s``, when no result arrives within
    ``timeout_s`` or when the node reports an error."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    from flex_ident.nodes.stiffness_identifier import LATCHED, RELIABLE, REQUEST_TOPIC, RESULT_TOPIC, STATUS_TOPIC

    request = {'bag': str(Path(bag).resolve()), 'experiment': str(Path(experiment).resolve()),
               'request_id': uuid.uuid4().hex}
    if out:
        request['out'] = str(Path(out).resolve())
    if method:
        request['method'] = method
    if diagnose is not None:
        request['diagnose'] = bool(diagnose)
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('flex_ident_request', context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    results = []
    try:
        node.create_subscription(
            String, RESULT_TOPIC, lambda m: results.append(m.data), LATCHED)
        if progress is not None:
            node.create_subscription(DiagnosticArray, STATUS_TOPIC, lambda m: progress(m), RELIABLE)
        pub = node.create_publisher(String, REQUEST_TOPIC, RELIABLE)
        deadline = time.monotonic() + discovery_timeout_s
        while pub.get_subscription_count() == 0:
            if time.monotonic() > deadline:
                raise RequestFailed(f'no stiffness_identifier node subscribes to {REQUEST_TOPIC} after '
                                    f'{discovery_timeout_s:g} s (start one: stiffness_identifier; same '
                                    f'ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE as this shell)')
            executor.spin_once(timeout_sec=0.05)
        pub.publish(String(data=json.dumps(request)))
        deadline = time.monotonic() + timeout_s
        while True:
            for text in results:
                try:
                    data = json.loads(text)
                except json.JSONDecodeError:
                    continue
                if isinstance(data, dict) and data.get('request_id') == request['request_id']:
                    if 'error' in data:
                        raise RequestFailed(f'the node reports: {data["error"]}')
                    return data
            results.clear()
            if time.monotonic() > deadline:
                raise RequestFailed(f'no result for the request after {timeout_s:g} s (the job may still be '
                                    f'running: see {STATUS_TOPIC}; raise --timeout)')
            executor.spin_once(timeout_sec=0.1)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def register(sub):
    p = sub.add_parser('request', help='send a request to a running stiffness_identifier node and print the result')
    p.add_argument('--bag', required=True, help='rosbag2 directory (as the node sees it)')
    p.add_argument('--experiment', required=True, help='experiment YAML')
    p.add_argument('--out', default=None, help="output directory (default: the node's)")
    p.add_argument('--method', default=None, help="optimizer (default: the node's parameter)")
    p.add_argument('--diagnose', dest='diagnose', action='store_true', default=None,
                   help='run the closed loop (default: the node\'s parameter)')
    p.add_argument('--no-diagnose', dest='diagnose', action='store_false', help='declared parameters only')
    p.add_argument('--timeout', type=float, default=600.0, help='seconds to wait for the result (default 600)')
    p.add_argument('--quiet', action='store_true', help='no progress lines on stderr')


def request_command(args) -> int:
    if not args.timeout > 0:
        raise ValueError(f'--timeout must be positive, got {args.timeout}')
    last = [None]

    def progress(msg):
        if not msg.status:
            return
        st = msg.status[0]
        if st.message != last[0] and st.message != 'idle':
            last[0] = st.message
            print(f'flex-ident request: {st.message}', file=sys.stderr, flush=True)

    report = send_request(args.bag, args.experiment, args.out, args.method, args.diagnose, args.timeout,
                          progress=None if args.quiet else progress)
    print(json.dumps(report, indent=2))
    return 0
