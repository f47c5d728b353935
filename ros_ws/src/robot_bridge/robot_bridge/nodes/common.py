"""ROS glue shared by the nodes of every package: parameters, message-type lookup and the standard main()."""
from __future__ import annotations

import faulthandler
import importlib
import math
import sys

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.executors import ExternalShutdownException


def declare_parameter(node, name: str, default, description: str, kind=None, check=None):
    """Declare a parameter that works the way ROS users set it, and return its validated value.

    Accepted from ``--ros-args -p name:=value``, a ``--params-file`` YAML and in-process overrides alike:
    the parameter is dynamically typed (so an empty list, ``rate:=2`` for a float, or ``topics:="[]"`` do not
    raise rclpy's type errors) and the value is coerced here to ``kind`` (default: the type of ``default``;
    ``list`` means a list of strings, ``FLOAT_LIST`` a list of finite numbers). ``check(value)`` returns an error text (the value's constraint, e.g.
    'must be > 0') or None. Bad values raise ValueError with one line naming the parameter, which
    :func:`run_node` prints as ``<node>: error: ...`` with a non-zero exit.
    """
    kind = kind or type(default)
    descriptor = ParameterDescriptor(description=description, dynamic_typing=True)
    value = node.declare_parameter(name, default, descriptor).value
    value = _coerce(name, value, kind, default)
    problem = check(value) if check is not None else None
    if problem:
        raise ValueError(f"parameter '{name}' {problem}, got {value!r}")
    return value


FLOAT_LIST = 'float list'


def _coerce(name, value, kind, default):
    def bad(expected):
        return ValueError(f"parameter '{name}' must be {expected}, got {value!r}")
    if kind == FLOAT_LIST:
        if value is None or (isinstance(value, (list, tuple, bytes)) and len(value) == 0):
            return []
        if (isinstance(value, (list, tuple)) and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                     for v in value)):
            values = [float(v) for v in value]
            if all(math.isfinite(v) for v in values):
                return values
        raise bad('a list of finite numbers')
    if kind is list:
        if value is None or (isinstance(value, (list, tuple, bytes)) and len(value) == 0):
            return []
        if isinstance(value, str):
            return [value] if value else []
        if isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value):
            return list(value)
        raise bad('a list of strings')
    if value is None:
        return default
    if kind is bool:
        if isinstance(value, bool):
            return value
        raise bad('true or false')
    if kind is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise bad('a number')
        value = float(value)
        if not math.isfinite(value):
            raise bad('a finite number')
        return value
    if kind is int:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or float(value) != int(value):
            raise bad('an integer')
        return int(value)
    if kind is str:
        if isinstance(value, bool) or isinstance(value, (list, tuple, bytes)):
            raise bad('a string')
        return str(value)
    raise TypeError(f'unsupported parameter kind {kind!r}')


def positive(value):
    return None if value > 0 else 'must be > 0'


def non_negative(value):
    return None if value >= 0 else 'must be >= 0'


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


TEARDOWN_TIMEOUT_S = 20.0     # the middleware's teardown after node.close(): longer means it hangs


def run_node(make_node, args=None, until=None) -> int:
    """Create a node and spin it until Ctrl-C, SIGTERM or ``until(node)`` is true; then clean up.

    ``make_node()`` may raise ValueError for bad parameters/inputs: it is printed as one line and the
    process exits with status 1. ``node.close()`` (if defined) runs before shutdown, so files are
    always closed cleanly. Returns the exit status (``node.exit_code`` if the node sets one). A teardown
    that hangs after ``close()`` is ended after ``TEARDOWN_TIMEOUT_S`` with every thread's stack on stderr.
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
    except Exception:
        # Ctrl-C or SIGTERM while the node was still starting: rclpy has shut the context down under it, and
        # whatever call came next failed. That is a requested stop, not an error; anything else is re-raised.
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            if hasattr(node, 'close'):
                node.close()             # the node's own files and threads: never cut short
        # From here only the middleware's teardown is left. Should it hang (CI once saw a node keep running 30 s
        # after SIGINT, after its work was done), a watchdog outside the GIL prints every thread's stack to stderr
        # and ends the process with status 1 instead of leaving it behind.
        faulthandler.dump_traceback_later(TEARDOWN_TIMEOUT_S, exit=True)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        faulthandler.cancel_dump_traceback_later()
    return int(getattr(node, 'exit_code', 0) or 0)


class LatestMessageWorker:
    """Hands the latest message to ``process(msg)`` in a worker thread, so slow processing never blocks a
    subscription; a message arriving while one is processed replaces any queued one (only the newest request
    counts). ``submit`` is the subscription callback; ``close`` stops the thread."""

    def __init__(self, process, name='worker'):
        import threading
        self._process = process
        self._pending = None
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name=name)
        self._thread.start()

    def submit(self, msg):
        with self._lock:
            self._pending = msg
        self._wake.set()

    def _run(self):
        while not self._stop.is_set():
            if not self._wake.wait(timeout=0.1):
                continue
            self._wake.clear()
            with self._lock:
                msg, self._pending = self._pending, None
            if msg is not None:
                self._process(msg)

    def close(self, timeout_s=30.0):
        self._stop.set()
        self._wake.set()
        self._thread.join(timeout=timeout_s)
