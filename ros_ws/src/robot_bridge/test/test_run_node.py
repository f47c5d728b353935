"""run_node, the standard main() of every node: a middleware teardown that hangs after the node's own close() is
ended by the watchdog with every thread's stack on stderr, instead of leaving the process behind."""
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent('''
    import time
    from rclpy.node import Node
    from robot_bridge.nodes import common

    common.TEARDOWN_TIMEOUT_S = 1.0
    closed = []

    class HangingTeardown(Node):
        def __init__(self):
            super().__init__('hanging_teardown')

        def close(self):
            closed.append(True)
            print('closed', flush=True)

        def destroy_node(self):
            time.sleep(60)             # stands in for a middleware teardown that never returns

    raise SystemExit(common.run_node(HangingTeardown, args=[], until=lambda node: True))
''')


def test_a_teardown_that_hangs_is_ended_with_the_stacks_on_stderr():
    proc = subprocess.run([sys.executable, '-c', SCRIPT], capture_output=True, text=True, timeout=30)
    assert proc.stdout.strip() == 'closed'           # the node's own close() ran in full first
    assert proc.returncode == 1, (proc.returncode, proc.stderr[-2000:])
    assert 'Timeout' in proc.stderr and 'destroy_node' in proc.stderr, proc.stderr[-2000:]


def test_a_normal_teardown_exits_cleanly():
    normal = SCRIPT.replace('time.sleep(60)', 'super().destroy_node()')
    proc = subprocess.run([sys.executable, '-c', normal], capture_output=True, text=True, timeout=30)
    assert proc.returncode == 0 and proc.stdout.strip() == 'closed', proc.stderr[-2000:]
