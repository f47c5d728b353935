"""ROS glue shared by the nodes of every package: message-type lookup and the standard main()."""
from __future__ import annotations

import importlib
import sys

import rclpy
from rclpy.executors import ExternalShutdownException


def message_class(msgtype: str):
    """'sensor_msgs/msg/JointState' (or 'sensor_msgs/JointState') -> the rclpy message class."""
    parts = msgtype.split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3:
        raise ValueError(f"'{msgtype}' is not a message type name like 'sensor_msgs/msg/JointState'")
    try:
        module = importlib.import_module(f'{parts[0]}.{parts[1]}')
        return getattr(module, parts[2])
    except (ImportError, AttributeError):
        raise ValueError(f"message type '{msgtype}' is not available in this ROS installation") from None


def run_node(make_node, args=None, until=None) -> int:
    """Create a node and spin it until Ctrl-C, SIGTERM or ``until(node)`` is true; then clean up.

    ``make_node()`` may raise ValueError for bad parameters/inputs: it is printed as one line and the
    process exits with status 1. ``node.close()`` (if defined) runs before shutdown, so files are
    always closed cleanly. Returns the exit status (``node.exit_code`` if the node sets one).
    """
    rclpy.init(args=args)
    node = None
    try:
        node = make_node()
        while rclpy.ok() and not (until and until(node)):
            rclpy.spin_once(node, timeout_sec=0.1)
    except ValueError as exc:
        name = node.get_name() if node else sys.argv[0].split('/')[-1]
        print(f'{name}: error: {exc}', file=sys.stderr)
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            if hasattr(node, 'close'):
                node.close()
            node.destroy_node()
        rclpy.try_shutdown()
    return int(getattr(node, 'exit_code', 0) or 0)
