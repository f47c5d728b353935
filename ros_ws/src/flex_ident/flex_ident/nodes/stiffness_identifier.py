"""stiffness_identifier: identify a flexible object's stiffness from a recorded bag, on request.

Requests (one job at a time; a request that arrives while a job runs is refused with a WARN status)
  /identification/request (std_msgs/String)  JSON {"bag": ..., "experiment": ..., "out": ..., "method": ...,
                                             "diagnose": true|false, "request_id": ...};
                                             keys left out take the parameter values; request_id (any string)
                                             is echoed in the result (``flex-ident request`` uses it)
  ~/run (std_srvs/Trigger)                   run with the current parameters; answers at once (the job runs in a
                                             worker thread and reports on the topics below)
Parameters
  bag (string)          rosbag2 directory (CONTRACTS.md section 1)
  experiment (string)   experiment YAML (CONTRACTS.md section 2)
  out (string)          output directory for report.json and plots (default: identification_<bag name>)
  method (string)       optimizer passed to the identification (default 'lm')
  diagnose (bool)       run the closed loop: find, add and identify effects the model lacks (default true)
  run_on_start (bool)   start a job with the parameters as soon as the node is up (default false)
  recorded_topic (string) identify every bag announced on this topic (std_msgs/String JSON {"bag": ...}, as
                        joint_state_logger publishes on /joint_state_logger/recorded when it closes a bag), with
                        the other parameters; default '' (off)
Publishes
  /identification/status (diagnostic_msgs/DiagnosticArray)  progress (stage, iteration, cost, fraction) while a job
                        runs, a 1 Hz heartbeat otherwise; level ERROR when a job fails
  /identification/result (std_msgs/String, reliable, transient local, depth 1: latched)  the report JSON
                        (CONTRACTS.md section 3), or {"error": ..., "error_type": ..., "request": ...}
  /identification/markers (visualization_msgs/MarkerArray, latched)  the identified loop: both branches at the
                        static equilibrium of the recording's first sample with the identified springs (frame 'base',
                        the arm's base frame); nothing for an arm-only experiment

The algorithm is flex_ident.identification.identify.run_identification; this node only moves requests and results.
"""
from __future__ import annotations

import json
import threading
import time
import traceback
from dataclasses import asdict, dataclass
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from flex_ident.identification.report import json_default
from robot_bridge.nodes.common import declare_parameter, run_node
from robot_bridge.nodes.markers import line_strip, marker_array

NODE_NAME = 'stiffness_identifier'
REQUEST_TOPIC = '/identification/request'
STATUS_TOPIC = '/identification/status'
RESULT_TOPIC = '/identification/result'
MARKER_TOPIC = '/identification/markers'
PROGRESS_MIN_PERIOD_S = 0.1
HEARTBEAT_PERIOD_S = 1.0

LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
RELIABLE = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def run_identification(bag_path, experiment_path, out_dir, method='lm', progress=None, diagnose=True) -> dict:
    """The identification (imported when first used, so the node starts even if it is unavailable)."""
    from flex_ident.identification.identify import run_identification as identify
    return identify(bag_path, experiment_path, out_dir, method=method, progress=progress, diagnose=diagnose)


class RequestError(ValueError):
    """A request the node cannot run (malformed JSON, missing bag or experiment)."""


@dataclass
class IdentificationRequest:
    bag: str
    experiment: str
    out: str
    method: str
    diagnose: bool = True
    request_id: str = ''

    @classmethod
    def from_values(cls, bag, experiment, out, method, diagnose=True, request_id='') -> 'IdentificationRequest':
        bag, experiment = str(bag or '').strip(), str(experiment or '').strip()
        if not bag:
            raise RequestError('no bag given (request key "bag" or parameter bag)')
        if not experiment:
            raise RequestError('no experiment given (request key "experiment" or parameter experiment)')
        out = str(out or '').strip() or f'identification_{Path(bag.rstrip("/")).name}'
        if not isinstance(diagnose, bool):
            raise RequestError(f'"diagnose" must be true or false, got {diagnose!r}')
        return cls(bag=bag, experiment=experiment, out=out, method=str(method or 'lm').strip() or 'lm',
                   diagnose=diagnose, request_id=str(request_id or ''))


class StiffnessIdentifier(Node):
    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        bag = declare_parameter(self, 'bag', '', 'rosbag2 directory to identify from')
        experiment = declare_parameter(self, 'experiment', '', 'experiment YAML')
        declare_parameter(self, 'out', '', 'output directory (default: identification_<bag name>)')
        declare_parameter(self, 'method', 'lm', 'optimizer: lm, lbfgsb or steepest')
        declare_parameter(self, 'diagnose', True,
                          'find, add and identify effects the model lacks (the closed loop; false: the '
                          'declared parameters only)')
        run_on_start = declare_parameter(self, 'run_on_start', False,
                                         'start a job with the parameters once the node is up')
        self._lock = threading.Lock()
        self._running = False      # a job is running: true from submit until just before its result goes out
        self._closed = False
        self._job_id = 0
        self._state = {'state': 'idle'}
        self._last_progress_time = 0.0
        self._last_stage = None
        self.status_pub = self.create_publisher(DiagnosticArray, STATUS_TOPIC, RELIABLE)
        self.result_pub = self.create_publisher(String, RESULT_TOPIC, LATCHED)
        self.marker_pub = self.create_publisher(MarkerArray, MARKER_TOPIC, LATCHED)
        self.request_sub = self.create_subscription(String, REQUEST_TOPIC, self._on_request, RELIABLE)
        self.run_srv = self.create_service(Trigger, '~/run', self._on_run)
        self._heartbeat = self.create_timer(HEARTBEAT_PERIOD_S, self._publish_heartbeat)
        self._start_timer = self.create_timer(0.0, self._start_from_parameters) if run_on_start else None
        recorded_topic = declare_parameter(self, 'recorded_topic', '',
                                           'identify every bag announced on this topic (JSON {"bag": ...})')
        if recorded_topic:
            self.recorded_sub = self.create_subscription(String, recorded_topic, self._on_recorded, LATCHED)
        self.get_logger().info(f'ready: publish JSON on {REQUEST_TOPIC} (e.g. with `flex-ident request`) or call '
                               f'{self.get_fully_qualified_name()}/run')
        if bag and experiment and not run_on_start:
            self.get_logger().info('bag and experiment are set but run_on_start is false: waiting for a request '
                                   '(add -p run_on_start:=true to identify them now)')

    # -- requests ------------------------------------------------------------------------------------------------
    @property
    def busy(self) -> bool:
        with self._lock:
            return self._running

    def _parameter_values(self) -> dict:
        values = {k: self.get_parameter(k).value for k in ('bag', 'experiment', 'out', 'method', 'diagnose')}
        return dict(values, request_id='')

    def _on_request(self, msg: String):
        try:
            data = json.loads(msg.data) if msg.data.strip() else {}
            if not isinstance(data, dict):
                raise RequestError(f'request must be a JSON object, got {type(data).__name__}')
            values = self._parameter_values()
            unknown = set(data) - set(values)
            if unknown:
                self.get_logger().warn(f'ignoring unknown request keys {sorted(unknown)}')
            values.update({k: v for k, v in data.items() if k in values and v is not None})
            request = IdentificationRequest.from_values(**values)
        except (json.JSONDecodeError, RequestError) as exc:
            self._report_error(exc, {'raw': msg.data})
            return
        self.submit(request)

    def _on_run(self, _request, response):
        try:
            request = IdentificationRequest.from_values(**self._parameter_values())
        except RequestError as exc:
            self._report_error(exc, self._parameter_values())
            response.success, response.message = False, str(exc)
            return response
        started, message = self.submit(request)
        response.success, response.message = started, message
        return response

    def _on_recorded(self, msg: String):
        values = self._parameter_values()
        try:
            data = json.loads(msg.data)
            if not isinstance(data, dict) or not data.get('bag'):
                raise RequestError(f'a recorded-bag announcement needs {{"bag": ...}}, got {msg.data[:200]!r}')
            values['bag'] = str(data['bag'])
            request = IdentificationRequest.from_values(**values)
        except (ValueError, RequestError) as exc:      # json.JSONDecodeError is a ValueError
            self._report_error(RequestError(str(exc)), values)
            return
        self.submit(request)

    def _start_from_parameters(self):
        self._start_timer.cancel()
        try:
            self.submit(IdentificationRequest.from_values(**self._parameter_values()))
        except RequestError as exc:
            self._report_error(exc, self._parameter_values())

    def submit(self, request: IdentificationRequest) -> tuple[bool, str]:
        """Start a job in the worker thread unless one is running. Returns (started, message)."""
        with self._lock:
            if self._closed:
                return False, 'node is shutting down'
            if self._running:
                message = f'busy with job {self._job_id}; request for {request.bag} refused'
                self._publish_status(DiagnosticStatus.WARN, message, self._state)
                self.get_logger().warn(message)
                return False, message
            self._job_id += 1
            self._running = True
            job_id = self._job_id
            self._state = {'state': 'running', 'job_id': job_id, **asdict(request)}
            self._last_stage = None
            message = f'job {job_id} started: {request.bag} with {request.experiment} -> {request.out}'
            self.get_logger().info(message)
            worker = threading.Thread(target=self._run_job, args=(job_id, request), daemon=True,
                                      name=f'identification_job_{job_id}')
            worker.start()
        return True, message

    # -- the job (worker thread) ---------------------------------------------------------------------------------
    def _run_job(self, job_id: int, request: IdentificationRequest):
        t0 = time.monotonic()
        self._publish_status(DiagnosticStatus.OK, f'job {job_id} started', self._state)

        def progress(info: dict):
            self._on_progress(job_id, t0, info)

        try:
            report = run_identification(request.bag, request.experiment, request.out, method=request.method,
                                        progress=progress, diagnose=request.diagnose)
            if not isinstance(report, dict):
                raise TypeError(f'identification returned {type(report).__name__}, expected a dict')
            text = json.dumps(dict(report, request_id=request.request_id) if request.request_id else report,
                              default=json_default)
        except Exception as exc:   # noqa: BLE001 - a failed job is reported, never crashes the node
            if not isinstance(exc, ValueError):
                self.get_logger().error(''.join(traceback.format_exception(exc)))
            with self._lock:     # idle before the error goes out: a client may send its next request at once
                self._state = {'state': 'idle', 'last_job': job_id, 'last_outcome': 'error'}
                self._running = False
            self._report_error(exc, asdict(request), job_id=job_id)
            return
        elapsed = time.monotonic() - t0
        self._publish_loop_markers(request, report)
        summary = {'state': 'done', 'job_id': job_id, 'elapsed_s': round(elapsed, 3), **asdict(request)}
        params = report.get('parameters')
        if isinstance(params, dict):
            summary.update({f'parameter.{k}': v for k, v in params.items()})
        self._publish_status(DiagnosticStatus.OK, f'job {job_id} done in {elapsed:.1f} s', summary)
        self.get_logger().info(f'job {job_id} done in {elapsed:.1f} s: {params}')
        with self._lock:     # idle before the result goes out: a client may send its next request at once
            self._state = {'state': 'idle', 'last_job': job_id, 'last_outcome': 'done'}
            self._running = False
        self._publish(self.result_pub, String(data=text))

    def _publish_loop_markers(self, request: IdentificationRequest, report: dict):
        """The identified loop as markers (a failure here is logged: the report is already out)."""
        params = report.get('parameters')
        if not isinstance(params, dict):
            return
        try:
            from flex_ident.identification.loop_shape import identified_loop_branches
            branches = identified_loop_branches(request.bag, request.experiment, params)
        except Exception as exc:   # noqa: BLE001
            self.get_logger().warn(f'no loop markers: {type(exc).__name__}: {exc}')
            return
        if branches:
            self._publish(self.marker_pub, marker_array(
                [line_strip('identified_loop', i, b, 'green', 0.01, 'base') for i, b in enumerate(branches)]))

    def _on_progress(self, job_id: int, t0: float, info: dict):
        now = time.monotonic()
        stage = info.get('stage') if isinstance(info, dict) else None
        with self._lock:
            self._state = {'state': 'running', 'job_id': job_id, **self._request_fields(),
                           **(info if isinstance(info, dict) else {'progress': info})}
            if stage == self._last_stage and now - self._last_progress_time < PROGRESS_MIN_PERIOD_S:
                return
            self._last_stage, self._last_progress_time = stage, now
            values = dict(self._state, elapsed_s=round(now - t0, 3))
        self._publish_status(DiagnosticStatus.OK, f'job {job_id}: {stage or "running"}', values)

    def _request_fields(self) -> dict:
        return {k: self._state[k] for k in ('bag', 'experiment', 'out', 'method') if k in self._state}

    # -- publishing ----------------------------------------------------------------------------------------------
    def _report_error(self, exc: Exception, request: dict, job_id: int | None = None):
        message = f'{type(exc).__name__}: {exc}'
        prefix = f'job {job_id} failed: ' if job_id is not None else 'request refused: '
        self.get_logger().error(prefix + message)
        self._publish_status(DiagnosticStatus.ERROR, prefix + message,
                             {'state': 'error', 'job_id': job_id if job_id is not None else '', **request})
        result = {'error': str(exc), 'error_type': type(exc).__name__, 'request': request}
        if isinstance(request, dict) and request.get('request_id'):
            result['request_id'] = request['request_id']
        self._publish(self.result_pub, String(data=json.dumps(result, default=json_default)))

    def _publish_heartbeat(self):
        if self.busy:
            return   # progress messages carry the state while a job runs
        with self._lock:
            values = dict(self._state)
        self._publish_status(DiagnosticStatus.OK, 'idle', values)

    def _publish_status(self, level: bytes, message: str, values: dict):
        if self._closed:
            return
        try:
            name, stamp = self.get_fully_qualified_name(), self.get_clock().now().to_msg()
        except Exception as exc:   # noqa: BLE001 - the node destroyed under a finishing job (its handle is gone)
            self.get_logger().debug(f'status not published, the node is shutting down: {exc}')
            return
        status = DiagnosticStatus(level=level, name=name, message=message, hardware_id='',
                                  values=[KeyValue(key=str(k), value=str(v)) for k, v in values.items()])
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = stamp
        self._publish(self.status_pub, msg)

    def _publish(self, publisher, msg):
        if self._closed:
            return
        try:
            publisher.publish(msg)
        except Exception as exc:   # noqa: BLE001 - e.g. the context shut down under a finishing job
            self.get_logger().debug(f'could not publish on {publisher.topic_name}: {exc}')

    def destroy_node(self):
        self.close()          # first, so that a job finishing in its thread publishes nothing on a destroyed node
        return super().destroy_node()

    def close(self):
        """Stop accepting requests; a running job is left to finish in its daemon thread (it cannot be cancelled)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            running = self._running
        if running:
            self.get_logger().warn(f'shutting down while job {self._job_id} runs; its result will not be published')


def main(args=None):
    return run_node(StiffnessIdentifier, args=args)


if __name__ == '__main__':
    raise SystemExit(main())
