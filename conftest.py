"""Test configuration for the whole workspace: DDS stays on loopback, and a per-test ROS context.

Every test process gets ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, a random ROS_DOMAIN_ID and a temporary
ROS_LOG_DIR before rclpy is imported anywhere (the Makefile and .ci/run set them too).
"""
import gc
import os
import random
import tempfile
import threading

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 100)))
os.environ.setdefault('ROS_LOG_DIR', tempfile.mkdtemp(prefix='ros_log_'))
os.environ.setdefault('MPLBACKEND', 'Agg')

import pytest  # noqa: E402


@pytest.fixture
def ros_context():
    """An initialised rclpy Context with a MultiThreadedExecutor spinning in a background thread.

    Yields an object with ``context``, ``executor`` and ``add(node)``; nodes added are destroyed and the
    context shut down at teardown. Pattern from rclpy's own tests (see docs: no launch_testing here).
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import MultiThreadedExecutor

    ctx = Context()
    rclpy.init(context=ctx, domain_id=int(os.environ['ROS_DOMAIN_ID']))
    executor = MultiThreadedExecutor(num_threads=4, context=ctx)
    nodes = []

    class Handle:
        context = ctx

        def __init__(self):
            self.executor = executor

        def add(self, node):
            nodes.append(node)
            executor.add_node(node)
            return node

    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    try:
        yield Handle()
    finally:
        for node in nodes:
            if hasattr(node, 'close'):
                node.close()
        executor.shutdown()
        thread.join(timeout=5)           # the spin loop has ended before any node goes away
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        # rclpy tasks that ended in an exception print it when finalised; they sit in reference cycles, so without
        # this the cyclic collector prints it later, inside whichever test runs then (seen once in CI: a stray
        # stderr line in a CLI test's one-line-error check)
        gc.collect()


#: every wait_for deadline is multiplied by this (TEST_WAIT_SCALE, default 3): the deadlines are upper bounds for
#: delivery and discovery, never performance claims, and a loaded CI machine once missed a 20 s one
WAIT_SCALE = float(os.environ.get('TEST_WAIT_SCALE', '3'))


def _wait_for(predicate, timeout_s=10.0, period_s=0.01):
    """Poll ``predicate`` until it is true or ``timeout_s`` x WAIT_SCALE passes; return its last value."""
    import time
    deadline = time.monotonic() + timeout_s * WAIT_SCALE
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(period_s)
    return predicate()


@pytest.fixture
def wait_for():
    """``wait_for(predicate, timeout_s=10)``: poll instead of sleeping for discovery or delivery."""
    return _wait_for


class _FiniteDifferences:
    """Central differences of a scalar function ``E(q)`` of a vector, for checking analytic derivatives."""

    @staticmethod
    def gradient(E, q, h=1e-6):
        import numpy as np
        I = np.eye(len(q))
        return np.array([(E(q + h * I[i]) - E(q - h * I[i])) / (2 * h) for i in range(len(q))])

    @staticmethod
    def hessian(E, q, h=1e-4):
        import numpy as np
        n = len(q)
        I = np.eye(n)
        H = np.zeros((n, n))
        for i in range(n):
            for j in range(i, n):
                H[i, j] = H[j, i] = (E(q + h * I[i] + h * I[j]) - E(q + h * I[i] - h * I[j])
                                     - E(q - h * I[i] + h * I[j]) + E(q - h * I[i] - h * I[j])) / (4 * h * h)
        return H


@pytest.fixture
def finite_differences():
    """``finite_differences.gradient(E, q, h=1e-6)`` and ``.hessian(E, q, h=1e-4)`` of a scalar function ``E``."""
    return _FiniteDifferences
