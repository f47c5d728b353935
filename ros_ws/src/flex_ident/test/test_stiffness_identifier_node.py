"""stiffness_identifier in one process: requests by topic and service, progress, latched result, errors.

The identification itself is replaced by a fake (monkeypatch), so these tests specify the node's ROS behaviour only.
DDS stays on loopback in a random domain with logs in a temp dir (also set by the workspace conftest, which provides
the ``ros_context`` fixture: own Context, MultiThreadedExecutor in a thread; ``wait_for`` polls instead of sleeping).
"""
import json
import os
import random
import tempfile
import threading

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 100)))
os.environ.setdefault('ROS_LOG_DIR', tempfile.mkdtemp(prefix='ros_log_'))

import pytest  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from flex_ident.nodes import stiffness_identifier as node_module  # noqa: E402
from flex_ident.nodes.stiffness_identifier import (  # noqa: E402
    REQUEST_TOPIC, RESULT_TOPIC, STATUS_TOPIC, StiffnessIdentifier)

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
REPORT = {'parameters': {'k_theta': 4.98, 'k_phi': 3.02}, 'parameter_std': {'k_theta': 0.05, 'k_phi': 0.04},
          'iterations': 3, 'wall_time_s': 0.01}


class FakeIdentification:
    """Stands in for flex_ident.identification.identify.run_identification; records calls, can block or fail."""

    def __init__(self, error=None, block=False):
        self.calls = []
        self.error = error
        self.release = threading.Event()
        self.entered = threading.Event()
        if not block:
            self.release.set()

    def __call__(self, bag_path, experiment_path, out_dir, method='lm', progress=None, diagnose=None):
        assert isinstance(diagnose, bool)       # the node always says whether to run the closed loop
        self.calls.append((bag_path, experiment_path, out_dir, method) + (('diagnose',) if diagnose else ()))
        self.entered.set()
        for i in range(3):
            progress({'stage': 'optimize', 'iteration': i, 'cost': 1.0 / (i + 1), 'fraction': (i + 1) / 3})
        assert self.release.wait(10)
        if self.error is not None:
            raise self.error
        return dict(REPORT)


class Listener(Node):
    """Collects status and result messages (the result subscription is latched, like the publisher)."""

    def __init__(self, context):
        super().__init__('identification_listener', context=context)
        self.status, self.results = [], []
        self.create_subscription(DiagnosticArray, STATUS_TOPIC, self.status.append, 50)
        self.create_subscription(String, RESULT_TOPIC, lambda m: self.results.append(json.loads(m.data)), LATCHED)
        self.request_pub = self.create_publisher(String, REQUEST_TOPIC, 10)
        self.run_client = self.create_client(Trigger, '/stiffness_identifier/run')

    def values(self, key):
        return [kv.value for arr in self.status for s in arr.status for kv in s.values if kv.key == key]

    def levels(self):
        return [s.level for arr in self.status for s in arr.status]


def start(ros_context, wait_for, monkeypatch, fake, **params):
    monkeypatch.setattr(node_module, 'run_identification', fake)
    overrides = [Parameter(k, value=v) for k, v in params.items()]
    node = ros_context.add(StiffnessIdentifier(context=ros_context.context, parameter_overrides=overrides))
    listener = ros_context.add(Listener(ros_context.context))
    assert wait_for(lambda: listener.request_pub.get_subscription_count() > 0
                    and node.result_pub.get_subscription_count() > 0
                    and node.status_pub.get_subscription_count() > 0)
    assert listener.run_client.wait_for_service(timeout_sec=10)
    return node, listener


def call_run(listener, wait_for):
    future = listener.run_client.call_async(Trigger.Request())
    assert wait_for(future.done)
    return future.result()


def test_topic_request_runs_the_job_with_parameter_fallbacks(ros_context, wait_for, monkeypatch, tmp_path):
    fake = FakeIdentification()
    node, listener = start(ros_context, wait_for, monkeypatch, fake, method='adjoint', out=str(tmp_path / 'o'))
    listener.request_pub.publish(String(data=json.dumps({'bag': 'b', 'experiment': 'e.yaml'})))
    assert wait_for(lambda: listener.results)
    assert listener.results[-1] == REPORT
    assert fake.calls == [('b', 'e.yaml', str(tmp_path / 'o'), 'adjoint', 'diagnose')]     # the closed loop by default
    listener.results.clear()
    listener.request_pub.publish(String(data=json.dumps({'bag': 'b2', 'experiment': 'e.yaml', 'diagnose': False})))
    assert wait_for(lambda: listener.results)
    assert fake.calls[-1] == ('b2', 'e.yaml', str(tmp_path / 'o'), 'adjoint')
    assert wait_for(lambda: 'done' in listener.values('state'))
    assert listener.values('stage').count('optimize') >= 1          # progress reached the status topic
    assert set(listener.levels()) == {DiagnosticStatus.OK}


def test_service_runs_with_current_parameters_and_refuses_while_busy(ros_context, wait_for, monkeypatch):
    fake = FakeIdentification(block=True)
    node, listener = start(ros_context, wait_for, monkeypatch, fake, bag='bag_dir', experiment='exp.yaml')
    first = call_run(listener, wait_for)
    assert first.success, first.message
    assert fake.entered.wait(10)
    second = call_run(listener, wait_for)        # callbacks are served while the job runs in its worker thread
    assert not second.success and 'busy' in second.message
    assert wait_for(lambda: DiagnosticStatus.WARN in listener.levels())
    fake.release.set()
    assert wait_for(lambda: listener.results)
    assert fake.calls == [('bag_dir', 'exp.yaml', 'identification_bag_dir', 'lm', 'diagnose')]
    assert wait_for(lambda: not node.busy)
    assert call_run(listener, wait_for).success  # free again


def test_failures_are_reported_and_the_node_keeps_serving(ros_context, wait_for, monkeypatch):
    fake = FakeIdentification(error=ValueError('bag has no /joint_states'))
    node, listener = start(ros_context, wait_for, monkeypatch, fake, experiment='exp.yaml')
    listener.request_pub.publish(String(data='{not json'))
    assert wait_for(lambda: listener.results)
    assert 'error' in listener.results[-1]
    response = call_run(listener, wait_for)       # no bag parameter
    assert not response.success and 'bag' in response.message
    listener.request_pub.publish(String(data=json.dumps({'bag': 'x'})))
    assert wait_for(lambda: any('no /joint_states' in r.get('error', '') for r in listener.results))
    assert listener.results[-1]['error_type'] == 'ValueError'
    assert listener.results[-1]['request']['bag'] == 'x'
    assert wait_for(lambda: DiagnosticStatus.ERROR in listener.levels())
    fake.error = None                             # the node is still alive and runs the next job
    listener.request_pub.publish(String(data=json.dumps({'bag': 'y'})))
    assert wait_for(lambda: listener.results[-1] == REPORT)


def test_result_is_latched_for_late_subscribers(ros_context, wait_for, monkeypatch):
    fake = FakeIdentification()
    node, listener = start(ros_context, wait_for, monkeypatch, fake, bag='b', experiment='e', run_on_start=True)
    assert wait_for(lambda: listener.results)
    late = ros_context.add(Listener(ros_context.context))
    assert wait_for(lambda: late.results)
    assert late.results == [REPORT]


@pytest.mark.parametrize('bad', ['[1, 2]', json.dumps({'experiment': 'e'}),
                                 json.dumps({'bag': 'b', 'experiment': 'e', 'diagnose': 'yes'})])
def test_malformed_requests_do_not_start_jobs(ros_context, wait_for, monkeypatch, bad):
    fake = FakeIdentification()
    node, listener = start(ros_context, wait_for, monkeypatch, fake)
    listener.request_pub.publish(String(data=bad))
    assert wait_for(lambda: listener.results)
    assert 'error' in listener.results[-1] and fake.calls == []
