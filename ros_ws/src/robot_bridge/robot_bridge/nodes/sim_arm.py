"""sim_arm: fake hardware, a MuJoCo arm from a URDF executing joint trajectories and publishing its joint states.

Subscribes  /arm_controller/joint_trajectory (trajectory_msgs/JointTrajectory, RELIABLE): joint names in any order,
            every arm joint present (else the command is ignored and logged; extra names are ignored);
            time_from_start counts from the header stamp (0: on receipt)
Publishes   /joint_states (sensor_msgs/JointState, RELIABLE, so best-effort and reliable subscribers both match):
            position, velocity, effort = the actuator torque as a joint torque sensor reads it (CONTRACTS.md
            section 1), stamped with simulation time mapped onto the clock at start

Parameters
  urdf (default: the project's Baxter right arm), base_link, tip_link, joints: the arm, as in arm_command_bridge
  experiment (string): an experiment YAML (CONTRACTS.md section 2) instead: the arm from it, and with
              hold_object:=true its clamped flexible loop (k_theta, k_phi [N m/rad]; the start pose closes the loop)
  initial_positions (double[]): start pose [rad] (default: Baxter's nominal pose / the middle of the limits)
  rate_hz (100; up to 1000), real_time_factor (1.0: simulation time runs with the wall clock)
  timestep (s, 0.001), bandwidth (rad/s, 40) and damping_ratio (1) of the joint controller
  Undeclared effects (all off by default): arm_viscous [N m s/rad], arm_coulomb [N m], loop_damping [N m s/rad],
  effort_bias [N m] (one or one per joint), effort_gain, position_delay [s], effort_delay [s],
  noise_position [rad], noise_velocity [rad/s], noise_effort [N m], seed
  excitation_s (double, 0 = off): run the example recordings' excitation itself (robot_bridge.sim.motion's
              SumOfSinesMotion, as bags/generate_example_bags.py records it): once /joint_states has a subscriber,
              hold still for the motion's rest (1 s), then excitation_s seconds of the faded sum of sines, the last
              0.5 s of them still again (so excitation_s >= 4.5: two 2 s fades and the end rest); commands received
              meanwhile replace it
  excitation_scale (double, 1.0): its amplitudes, times the default ones (the 6-link example bag used 0.6)
  stop_after_excitation (bool, false): stop publishing /joint_states when the excitation is done, so that a
              joint_state_logger with close_after_idle_s closes its bag (and stiffness_identifier with
              recorded_topic identifies it)

The simulation runs in its own thread, stepping 1/timestep times per simulated second; trajectory callbacks only hand
the command over.
"""
from __future__ import annotations

import threading
import time

import numpy as np
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.time import Time
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from robot_bridge.kinematics.arm import BAXTER_RIGHT_JOINTS, default_urdf_path
from robot_bridge.nodes.common import run_node
from robot_bridge.sim.arm_follower import ArmFollower, ExcitationReference
from robot_bridge.sim.experiment import ArmSpec, ExperimentSpec, load_experiment
from robot_bridge.sim.mjcf_builder import Numerics
from robot_bridge.sim.motion import SumOfSinesMotion
from robot_bridge.sim.mujoco_loop import Controller, Effects, MeasurementNoise

COMMAND_TOPIC = '/arm_controller/joint_trajectory'
MAX_RATE_HZ = 1000.0
MAX_LAG_S = 0.05        # behind the wall clock by more than this: fall back instead of catching up
BEHIND_PAUSE_S = 2e-4   # pause per step while behind the wall clock (releases the GIL to the executor threads)


class SimArm(Node):
    def __init__(self, **kwargs):
        super().__init__('sim_arm', **kwargs)

        def param(name, default, description, low=None, high=None):
            desc = ParameterDescriptor(description=description, dynamic_typing=True)
            if low is not None:
                desc.floating_point_range = [FloatingPointRange(from_value=low, to_value=high, step=0.0)]
                desc.dynamic_typing = False
            return self.declare_parameter(name, default, desc).value

        urdf = param('urdf', '', 'arm URDF (empty: the project\'s Baxter right arm)')
        base_link = param('base_link', 'base', 'base frame of the arm')
        tip_link = param('tip_link', 'right_gripper', 'tip link')
        joints = list(param('joints', list(BAXTER_RIGHT_JOINTS), 'arm joints'))
        experiment = param('experiment', '', 'experiment YAML (arm, and the loop with hold_object)')
        hold_object = bool(param('hold_object', False, 'hold the experiment\'s clamped loop'))
        k_theta = float(param('k_theta', 5.0, 'loop in-plane stiffness [N m/rad]'))
        k_phi = float(param('k_phi', 3.0, 'loop out-of-plane stiffness [N m/rad]'))
        q0 = [float(v) for v in param('initial_positions', [0.0], 'start pose [rad] ([0]: default)')]
        self.rate_hz = param('rate_hz', 100.0, 'joint state rate [Hz]', 1.0, MAX_RATE_HZ)
        self.real_time_factor = param('real_time_factor', 1.0, 'simulated seconds per wall second', 0.01, 100.0)
        timestep = param('timestep', 1e-3, 'simulation timestep [s]', 1e-5, 1e-2)
        controller = Controller(bandwidth_rad_s=float(param('bandwidth', 40.0, 'controller bandwidth [rad/s]')),
                                damping_ratio=float(param('damping_ratio', 1.0, 'controller damping ratio')))
        bias = [float(v) for v in param('effort_bias', [0.0], 'torque sensor bias [N m], 1 or per joint')]
        effects = Effects(
            arm_viscous_nms=float(param('arm_viscous', 0.0, 'added arm joint viscous friction [N m s/rad]')),
            arm_coulomb_nm=float(param('arm_coulomb', 0.0, 'arm joint Coulomb friction [N m]')),
            loop_damping_nms=float(param('loop_damping', 0.0, 'loop joint viscous damping [N m s/rad]')),
            effort_bias_nm=bias[0] if len(bias) == 1 else bias,
            effort_gain=float(param('effort_gain', 1.0, 'torque sensor gain')),
            position_delay_s=float(param('position_delay', 0.0, 'encoder delay [s]')),
            effort_delay_s=float(param('effort_delay', 0.0, 'torque sensor delay [s]')))
        noise = MeasurementNoise(float(param('noise_position', 0.0, 'position noise std [rad]')),
                                 float(param('noise_velocity', 0.0, 'velocity noise std [rad/s]')),
                                 float(param('noise_effort', 0.0, 'effort noise std [N m]')))
        seed = int(param('seed', 0, 'noise seed'))
        excitation_s = float(param('excitation_s', 0.0, 'seconds of the example excitation after the rest (0: off)'))
        excitation_scale = float(param('excitation_scale', 1.0, 'excitation amplitudes / the default ones'))
        self.stop_after_excitation = bool(param('stop_after_excitation', False,
                                                'stop publishing when the excitation is done'))
        if experiment:
            spec = load_experiment(experiment)
        else:
            spec = ExperimentSpec(ArmSpec(urdf or default_urdf_path(), base_link, tip_link, joints), None,
                                  np.array([0.0, 0.0, -9.81]))
        if hold_object and spec.loop is None:
            raise ValueError('hold_object needs an experiment YAML with an object')
        self.follower = ArmFollower(spec, None if q0 == [0.0] else q0, effects, noise,
                                    controller, with_object=hold_object, k_theta=k_theta, k_phi=k_phi,
                                    numerics=Numerics(timestep_s=timestep), seed=seed)
        self.names = self.follower.joint_names
        self.excitation: ExcitationReference | None = None     # set while waiting for a subscriber
        self.excitation_started_s: float | None = None        # simulation time at which it started (None: not yet)
        if excitation_s != 0:
            default = SumOfSinesMotion()
            shortest = 2 * default.ramp_s + default.end_rest_s
            if excitation_s < shortest:
                raise ValueError(f'excitation_s must be 0 (off) or at least {shortest:g} s (two {default.ramp_s:g} s '
                                 f'fades and the {default.end_rest_s:g} s end rest), got {excitation_s:g}')
            motion = SumOfSinesMotion(amplitudes_rad=tuple(excitation_scale * np.asarray(default.amplitudes_rad)))
            self.excitation = self.follower.excitation(motion.rest_s + excitation_s, motion)
        self._lock = threading.Lock()
        self._pending = None
        self.commands_received = 0
        self.published = 0                    # /joint_states messages published
        self.slower_than_real_time = 0        # times the simulation fell behind the wall clock
        self.error: str | None = None
        self.trajectory_start_s: float | None = None     # simulation time at which the last command started
        self.stamp0 = self.get_clock().now()
        self.pub = self.create_publisher(JointState, '/joint_states', QoSProfile(
            depth=100, reliability=ReliabilityPolicy.RELIABLE))
        self.create_subscription(JointTrajectory, COMMAND_TOPIC, self._on_trajectory,
                                 QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='sim_arm', daemon=True)
        self._thread.start()
        self.get_logger().info(f'simulating {len(self.names)} joints{" + the clamped loop" if hold_object else ""}'
                               f', publishing /joint_states at {self.rate_hz:g} Hz')

    def sim_time_to_stamp(self, t_s: float):
        return (self.stamp0 + Duration(nanoseconds=int(round(t_s * 1e9)))).to_msg()

    def _on_trajectory(self, msg: JointTrajectory):
        order = {n: i for i, n in enumerate(msg.joint_names)}
        missing = [n for n in self.names if n not in order]
        if missing or not msg.points:
            why = 'it has no points' if not msg.points else f'it lacks joints {missing}'
            self.get_logger().error(f'ignored a trajectory: {why}')
            return
        idx = [order[n] for n in self.names]
        t = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in msg.points])
        q = np.array([[p.positions[i] for i in idx] for p in msg.points])
        with_vel = all(len(p.velocities) == len(msg.joint_names) for p in msg.points)
        qd = np.array([[p.velocities[i] for i in idx] for p in msg.points]) if with_vel else None
        start = Time.from_msg(msg.header.stamp)
        start_s = None if start.nanoseconds == 0 else (start - self.stamp0).nanoseconds * 1e-9
        with self._lock:
            self._pending = (t, q, qd, start_s)

    def _run(self):
        try:
            self._simulate()
        except RuntimeError as exc:          # the simulation diverged: say so and stop publishing
            if not self.context.ok():        # Ctrl-C: the context went away under a publish; not an error
                return
            self.error = str(exc)
            self.get_logger().error(f'simulation stopped: {exc}')

    def _simulate(self):
        f = self.follower
        period = 1.0 / self.rate_hz
        wall0 = time.monotonic()
        k = 0
        while not self._stop.is_set():
            with self._lock:
                pending, self._pending = self._pending, None
            if pending is not None:
                try:
                    f.command(*pending)
                    self.excitation = None          # a command replaces an excitation not started yet
                    self.commands_received += 1
                    self.trajectory_start_s = f.reference.t0_s
                except ValueError as exc:
                    self.get_logger().error(f'ignored a trajectory: {exc}')
            if self.excitation is not None and self.pub.get_subscription_count() > 0:
                excitation, self.excitation = self.excitation, None
                excitation.t0_s = self.excitation_started_s = f.t_s
                f.reference = excitation
                self.get_logger().info(f'excitation started ({excitation.duration_s:g} s, rests included)')
            if self.excitation_done and self.stop_after_excitation:
                self.get_logger().info('excitation done: stopped publishing /joint_states')
                return
            f.advance_to(k * period)
            q, qd, tau = f.measure()
            msg = JointState(name=self.names, position=q.tolist(), velocity=qd.tolist(), effort=tau.tolist())
            msg.header.stamp = self.sim_time_to_stamp(f.t_s)
            self.pub.publish(msg)
            self.published += 1
            k += 1
            delay = wall0 + k * period / self.real_time_factor - time.monotonic()
            if delay > 0:
                self._stop.wait(delay)
            else:
                # Behind the wall clock (a loaded machine): never try to catch up in a burst, which would hold the
                # GIL in a tight loop and starve the executor threads that deliver /joint_states and the commands
                # (time.sleep(0) was not enough: CI once saw a probe in this process receive fewer than 300 messages
                # in 20 s). A real pause each step releases the GIL to them; the simulation runs slower than real
                # time instead, and the stamps are simulation time either way.
                self._stop.wait(BEHIND_PAUSE_S)
                if -delay > MAX_LAG_S:
                    wall0 -= delay
                    self.slower_than_real_time += 1
                    self.get_logger().warn('simulating slower than real time (machine loaded); stamps stay '
                                           'simulation time', throttle_duration_sec=10.0)

    @property
    def sim_time_s(self) -> float:
        return self.follower.t_s

    @property
    def excitation_done(self) -> bool:
        """The excitation (excitation_s > 0) has run to its end (or a command replaced it)."""
        return (self.excitation_started_s is not None
                and (self.commands_received > 0 or self.follower.t_s >= self.follower.reference.t_end_s))

    @property
    def trajectory_done(self) -> bool:
        return self.commands_received > 0 and self._pending is None and self.follower.trajectory_done

    def close(self):
        self._stop.set()
        self._thread.join(timeout=5)


def main(args=None) -> int:
    return run_node(lambda: SimArm(), args=args)


if __name__ == '__main__':
    raise SystemExit(main())
