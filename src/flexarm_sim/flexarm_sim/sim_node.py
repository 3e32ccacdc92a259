"""Simulated robot controller: the flexible arm behind ros2_control's topic contract.

Executes ``/forward_position_controller/commands`` and
``/joint_trajectory_controller/joint_trajectory`` (checked against the joint limits) and
follows the payload declared on ``/payload``; publishes ``/joint_states``, the simulation
``/clock`` (or follows another arm's), the tip camera (``/camera/image_raw``,
``/camera/camera_info``) and the ground truth on ``/sim/tip_pose_truth``, for evaluation only.
The arm is :mod:`flexarm_sim.plant` (deflection) and :mod:`flexarm_sim.dynamics` (joints and
vibration), a real arm's errors are :mod:`flexarm_sim.errors` and :mod:`flexarm_sim.true_camera`,
the one ``/clock`` of a domain :mod:`flexarm_sim.clock_share`; this node steps them in
simulated time and publishes what someone consumes.

Explained in docs/nodes.md#the-simulator-flexarm_sim.
"""
from __future__ import annotations

import time

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import QoSDurabilityPolicy, QoSProfile
from rclpy.subscription import Subscription
from rclpy.timer import Timer
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Float64, Float64MultiArray, Header
from trajectory_msgs.msg import JointTrajectory

from flexarm_core import liveness, topics
from flexarm_core.frames import BASE_FRAME, PLANE_FRAME
from flexarm_core.goal_sender import full_name
from flexarm_core.health_report import OK, CommandLog, Status, status
from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry, command_error
from flexarm_core.ros.diagnostics import DiagnosticsPublisher
from flexarm_core.ros.node_main import run
from flexarm_core.ros.node_params import declare, declare_tree
from flexarm_core.ros.trajectory_message import trajectory_from
from flexarm_msgs.msg import PlanarPose, TipPose
from flexarm_sim.clock_share import OWN, ClockShare, yields
from flexarm_sim.dynamics import ArmDynamics, ArmState
from flexarm_sim.errors import ArmErrors, active
from flexarm_sim.plant import Plant
from flexarm_sim.true_camera import true_renderer
from flexarm_vision.camera_info import camera_info
from flexarm_vision.camera_model import CameraModel

FABRICATION = ('link3', 'link4', 'offset')   # writable plant.fabrication.* [m]

FOLLOW_CATCH_UP = 200    # steps at most on one /clock, following (2 s of sim time)
WALL_CATCH_UP = 200      # steps at most a wake-up on the wall clock
WALL = 'wall'            # clock_source of a stand-in for a real controller
CLOCK_SILENCE = 1.0      # [s, wall; liveness-scaled] of silent /clock before a takeover
CLOCK_CHECK = 0.5        # [s, wall] between looks at the domain's /clock publishers
ACHIEVED_SPAN = 1.0      # [s, wall] the achieved real-time factor is measured over at least
CAMERA_FRAME = 'tip_camera_optical_frame'   # flexarm_description's URDF


def ticks_at(sec: int, nanosec: int, rate: float) -> int:
    """The whole ticks of ``rate`` Hz up to the time (sec, nanosec): :func:`tick_time`'s
    inverse (exact for the times it gives)."""
    numerator, denominator = float(rate).as_integer_ratio()
    return -(-((sec * 1_000_000_000 + nanosec) * numerator) // (1_000_000_000 * denominator))


def ticks_now(rate: float) -> int:
    """The whole ticks of ``rate`` Hz of the wall clock up to now (never ahead of it)."""
    numerator, denominator = float(rate).as_integer_ratio()
    return time.time_ns() * numerator // (1_000_000_000 * denominator)


def tick_time(tick: int, rate: float) -> tuple[int, int]:
    """(sec, nanosec) after ``tick`` ticks of ``rate`` Hz, in exact integer arithmetic."""
    numerator, denominator = float(rate).as_integer_ratio()
    return divmod(tick * 1_000_000_000 * denominator // numerator, 1_000_000_000)


def controller_status(node: str, hardware_id: str, moving: bool, sim_time: float,
                      factor: float, achieved: float, payload: float,
                      clock: str = 'publishes /clock') -> Status:
    """``<node>: controller``: the arm moving or still, the simulated time, the real-time
    factor achieved over the last 1-2 s and the one set, the payload, the simulator's part
    in the domain's ``/clock`` (:meth:`ClockShare.text`; in the message unless it simply publishes
    it). Always OK: the simulator has no failure state, and running slower than its factor is
    how it meets a busy CPU (it never skips steps), not a fault; a follower whose ``/clock``
    stops takes it over within ``CLOCK_SILENCE``."""
    return status(node, 'controller', OK, (
        f'arm {"moving" if moving else "still"}, x{achieved:.2f} real time (set x{factor:g}), '
        f'payload {payload:g} kg' + ('' if clock == 'publishes /clock' else f'; {clock}')), {
        'arm': 'moving' if moving else 'still', 'sim time [s]': round(sim_time, 3),
        'real-time factor': round(achieved, 3), 'real-time factor set': factor,
        'payload [kg]': payload, 'clock': clock}, hardware_id)


class SimNode(Node):

    def __init__(self, node_name: str = 'flexarm_sim') -> None:
        super().__init__(node_name)
        clock_source, clock_rate, camera_rate = self._declare_rates()
        plant = self._build_arm()
        self._dt = 1.0 / self._js_rate
        self._camera_every = max(1, round(self._js_rate / camera_rate))
        self._tick = 0
        # Every node on sim time wakes up for each /clock message, and a wake-up costs an
        # idle rclpy node ~0.8 ms of CPU here (0.08 core at 100 a second); 25 a second (a node's
        # time moves in steps of 40 ms wall) is plenty for waits of seconds.
        self._clock_every = max(1, round(self._js_rate * self._rtf / clock_rate))   # ticks
        self._commands = CommandLog()
        self._hardware_id = ''      # the controller's: none for the simulator
        # (wall time, tick) marks at least ACHIEVED_SPAN apart: the achieved real-time factor
        # is measured from the older one, over 1-2 s whenever a report is asked for
        self._marks = [(time.monotonic(), 0)] * 2
        self._open_interfaces(clock_source)
        self.get_logger().info(
            f'simulating at {self._js_rate:.0f} Hz x{self._rtf:g} real time, camera '
            f'{camera_rate:g} Hz, payload {plant.payload:g} kg')

    def _declare_rates(self) -> tuple[str, float, float]:
        """The simulator's timing (config/sim.yaml, whose ranges keep every rate positive):
        the real-time factor and joint-state rate kept, the clock source and the ``/clock``
        and camera rates returned."""
        self._rtf = declare(self, 'real_time_factor', 'config/sim.yaml')
        self._js_rate = declare(self, 'joint_state_rate', 'config/sim.yaml')
        clock_rate = declare(self, 'clock_rate', 'config/sim.yaml')
        camera_rate = declare(self, 'camera_rate', 'config/sim.yaml')
        clock_source = declare(self, 'clock_source', 'config/sim.yaml')
        self._wall = clock_source == WALL
        if self._wall:
            self._rtf = 1.0
        return clock_source, clock_rate, camera_rate

    def _build_arm(self) -> Plant:
        """The simulated arm at its start, its errors and its camera (config/arm.yaml, sim.yaml,
        camera.yaml); its plant."""
        self._geometry = ArmGeometry.from_dict(declare_tree(self, 'arm', 'config/arm.yaml'))
        plant = Plant.from_dict(declare_tree(self, 'plant', 'config/sim.yaml', {
            'payload', *(f'fabrication.{name}' for name in FABRICATION)}), self._geometry)
        errors = declare_tree(self, 'error_sources', 'config/sim.yaml')
        self._payload_changes = active(errors, 'payload')
        self._fabrication_changes = bool(errors['enabled'])
        initial = declare(self, 'initial_positions', 'config/sim.yaml')
        self._dynamics = ArmDynamics(
            plant, self._geometry, declare_tree(self, 'dynamics', 'config/sim.yaml'),
            np.asarray(initial, dtype=float), ArmErrors.from_dict(errors, plant.backlash))
        cam = {key: declare_tree(self, key, 'config/camera.yaml')
               for key in ('plate', 'camera', 'camera_render')}
        self._camera = true_renderer(cam, errors)
        self._calibration = CameraModel.from_dict(cam['camera']).intrinsics
        self._rng = np.random.default_rng(declare(self, 'seed', 'config/sim.yaml'))
        return plant

    def _open_interfaces(self, clock_source: str) -> None:
        """The publishers, the joint interface, the clock in its role, the parameter and
        payload handlers and the diagnostics."""
        latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
        self._share = ClockShare(OWN if self._wall else clock_source,
                                 self.get_fully_qualified_name(),
                                 liveness.limit(CLOCK_SILENCE), 2 * self._clock_every,
                                 time.monotonic())
        self._clock_pub: Publisher | None = None
        self._wake: Timer | None = None
        self._clock_sub: Subscription | None = None
        self._started_following = False        # the first /clock followed sets the time
        self._truth_pub = self.create_publisher(TipPose, topics.TIP_POSE_TRUTH, 10)
        self._image_pub = self.create_publisher(Image, topics.CAMERA_IMAGE, 5)
        self._info_pub = self.create_publisher(CameraInfo, topics.CAMERA_INFO, latched)
        self._setup_joint_io()
        self._camera_info = self._make_camera_info()
        self._info_pub.publish(self._camera_info)
        steady = RosClock(clock_type=ClockType.STEADY_TIME)
        if self._wall:
            self._tick = ticks_now(self._js_rate)
            self._wake = self.create_timer(self._clock_every * self._dt, self._on_wall,
                                           clock=steady)
        elif clock_source == OWN:
            self._own_clock()
        else:
            self._listen_to_clock(True)
        if not self._wall:
            self.create_timer(CLOCK_CHECK, self._check_clock, clock=steady)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.create_subscription(Float64, topics.PAYLOAD, self._on_payload, latched)
        self._diagnostics = DiagnosticsPublisher(self, self.statuses, stamp=self._now)

    # --- the controller's joint interface: ROS topics here, TCP in the fake controller ------
    def _setup_joint_io(self) -> None:
        self._js_pub = self.create_publisher(JointState, topics.JOINT_STATES, 10)
        self.create_subscription(Float64MultiArray, topics.JOINT_COMMANDS,
                                 lambda msg: self.apply_command(list(msg.data)), 10)
        self.create_subscription(JointTrajectory, topics.JOINT_TRAJECTORY,
                                 self.apply_trajectory, 10)

    def _joints_wanted(self) -> bool:
        """Whether a tick's joint state has anyone to go to."""
        return self._js_pub.get_subscription_count() > 0

    def _publish_joints(self, now: TimeMsg, state: ArmState) -> None:
        self._js_pub.publish(JointState(
            header=self._header(now, BASE_FRAME), name=list(JOINT_NAMES),
            position=state.joint_positions.tolist(), velocity=state.joint_velocities.tolist()))

    def apply_command(self, values: list[float]) -> str | None:
        """Execute a joint command; the reason it was refused (arm not moved), or None."""
        reason = command_error(values, self._geometry)
        self._commands.record(reason)
        if reason is not None:
            self.get_logger().error(f'joint command rejected, arm not moved: {reason}')
            return reason
        self._dynamics.command(np.asarray(values, dtype=float))
        return None

    def apply_trajectory(self, msg: JointTrajectory) -> str | None:
        """Follow a joint trajectory (none: hold); the reason it was refused (arm not moved),
        or None."""
        if not msg.points:
            self._commands.record(None)
            self.hold()
            return None
        trajectory, reason = None, None
        try:
            trajectory = trajectory_from(msg)
            reason = next(filter(None, (command_error(q.tolist(), self._geometry)
                                        for q in trajectory.positions)), None)
        except ValueError as error:
            reason = str(error)
        self._commands.record(reason)
        if reason is not None:
            self.get_logger().error(f'joint trajectory rejected, arm not moved: {reason}')
            return reason
        self._dynamics.follow(trajectory)
        return None

    def hold(self) -> None:
        """Stop the arm where it is (e.g. when the link to the PC is lost)."""
        self._dynamics.hold()

    def statuses(self) -> list[Status]:
        """The node's health (docs/nodes.md): controller, commands."""
        wall, tick = time.monotonic(), self._tick
        if wall - self._marks[1][0] >= ACHIEVED_SPAN:
            self._marks = [self._marks[1], (wall, tick)]
        since, then = self._marks[0]
        achieved = (tick - then) * self._dt / max(wall - since, 1e-9)
        return [controller_status(self.get_name(), self._hardware_id,
                                  self._dynamics.state.is_moving, tick * self._dt, self._rtf,
                                  achieved, self._dynamics.plant.payload,
                                  'wall clock, no /clock' if self._wall
                                  else self._share.text(self._dt)),
                self._commands.status(self.get_name(), self._hardware_id)]

    def _on_payload(self, msg: Float64) -> None:
        """The graph declares the payload: the arm carries it from now on (``plant.payload``
        follows, so the parameter always says what the arm carries)."""
        if msg.data == self._dynamics.plant.payload:
            return
        result = self.set_parameters([Parameter('plant.payload', Parameter.Type.DOUBLE,
                                                float(msg.data))])[0]
        if not result.successful:
            self.get_logger().error(f'/payload {msg.data:g} kg ignored: {result.reason}')

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """A new ``plant.payload`` [kg] loads the tip at once, if payload changes are on; new
        ``plant.fabrication`` link errors [m] bend the arm, if error sources are on."""
        plant = self._dynamics.plant
        errors = {'link3': plant.link3_error, 'link4': plant.link4_error,
                  'offset': plant.offset_error}
        for param in params:
            name = param.name.removeprefix('plant.fabrication.')
            if name in FABRICATION:
                if not self._fabrication_changes:
                    return SetParametersResult(successful=False, reason=(
                        'run-time link changes need error sources on (config/sim.yaml '
                        'error_sources.enabled)'))
                if param.type_ not in (Parameter.Type.DOUBLE, Parameter.Type.INTEGER):
                    return SetParametersResult(successful=False, reason=f'{name}: a number [m]')
                errors[name] = float(param.value)
        if any(p.name.removeprefix('plant.fabrication.') in FABRICATION for p in params):
            self._dynamics.set_fabrication(**errors)
            self.get_logger().info('link errors now ' + ', '.join(
                f'{k} {v * 1e3:.3f} mm' for k, v in errors.items()))
        for param in params:
            if param.name != 'plant.payload':
                continue
            if not self._payload_changes:
                return SetParametersResult(successful=False, reason=(
                    'run-time payload changes are off (config/sim.yaml error_sources.payload)'))
            if param.type_ not in (Parameter.Type.DOUBLE, Parameter.Type.INTEGER):
                return SetParametersResult(successful=False, reason='payload: a number [kg]')
            try:
                self._dynamics.set_payload(float(param.value))
            except ValueError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
            self.get_logger().info(f'payload now {param.value:g} kg')
        return SetParametersResult(successful=True)

    # --- the domain's one /clock (clock_share) ----------------------------------------------
    def _own_clock(self) -> None:
        """Publish /clock and step on the wall timer from the time reached."""
        self._clock_pub = self.create_publisher(Clock, topics.CLOCK, 10)
        self._wake = self.create_timer(self._clock_every * self._dt / self._rtf, self._on_wake)

    def _listen_to_clock(self, listen: bool) -> None:
        if listen and self._clock_sub is None:
            self._clock_sub = self.create_subscription(Clock, topics.CLOCK, self._on_clock, 10)
        elif not listen and self._clock_sub is not None:
            self.destroy_subscription(self._clock_sub)
            self._clock_sub = None

    def _other_clocks(self) -> list[str]:
        """The node names of the domain's /clock publishers other than this node."""
        names = {full_name(p.node_namespace, p.node_name)
                 for p in self.get_publishers_info_by_topic(topics.CLOCK)}
        return sorted(names - {self._share.name})

    def _check_clock(self) -> None:
        """A publisher listens while another /clock is published; a follower whose /clock went
        silent takes it over."""
        share, others = self._share, self._other_clocks()
        if share.role == OWN:
            self._listen_to_clock(bool(others))
            return
        if others:
            share.publisher = others[0]
        if share.silent(time.monotonic()):
            self._take_over(f'no /clock for {share.silence:g} s')

    def _take_over(self, why: str) -> None:
        self._share.take_over(self._tick)
        self._own_clock()
        self.get_logger().warning(
            f'{why}: this simulator publishes /clock from now on, from '
            f'{self._tick * self._dt:.3f} s '
            f'(it followed {self._share.took_over[0] or "another arm"})')

    def _on_clock(self, msg: Clock) -> None:
        """Following: step up to the publisher's time (the first /clock: start there, at rest).
        Owning: another publisher's /clock decides which of the two yields."""
        tick = ticks_at(msg.clock.sec, msg.clock.nanosec, self._js_rate)
        share = self._share
        if share.is_own(tick):
            return
        if share.role == OWN:
            others = self._other_clocks()
            other = others[0] if others else ''
            if not yields(self._tick, share.name, tick, other, share.margin):
                return
            self.destroy_timer(self._wake)
            self.destroy_publisher(self._clock_pub)
            self._wake = self._clock_pub = None
            share.follow(other, time.monotonic())
            self.get_logger().warning(f'/clock of {other or "another arm"} at '
                                      f'{tick * self._dt:.3f} s: following it')
        if share.heard(time.monotonic(), tick, self._tick):
            self._take_over(
                f'/clock went back to {tick * self._dt:.3f} s (its publisher restarted)')
            return
        if not self._started_following or (tick - self._tick > FOLLOW_CATCH_UP
                                           and not self._dynamics.state.is_moving):
            self.get_logger().info(f'following /clock from {tick * self._dt:.3f} s')
            self._started_following, self._tick = True, max(self._tick, tick)
        for _ in range(min(tick - self._tick, FOLLOW_CATCH_UP)):
            self._advance()

    def _on_wake(self) -> None:
        """Owning the clock: step one clock period (its last tick publishes /clock)."""
        for _ in range(self._clock_every):
            self._advance()

    def _on_wall(self) -> None:
        """On the wall clock: step up to now."""
        due = ticks_now(self._js_rate)
        for _ in range(min(due - self._tick, WALL_CATCH_UP)):
            self._advance()

    def _advance(self) -> None:
        """One tick: step the arm, then publish what is due and has a subscriber (the state
        and the stamp are built only then: at 10x real time an idle arm ticks 1000 times a
        wall second with nobody listening to most of it)."""
        self._dynamics.step(self._dt)
        self._tick += 1
        clock_due = self._clock_pub is not None and self._tick % self._clock_every == 0
        joints = self._joints_wanted()
        truth = self._truth_pub.get_subscription_count() > 0
        image = (self._tick % self._camera_every == 0
                 and self._image_pub.get_subscription_count() > 0)
        if not (clock_due or joints or truth or image):
            return
        now = self._now()
        if clock_due:
            self._clock_pub.publish(Clock(clock=now))
            self._share.published(self._tick)
        if not (joints or truth or image):
            return
        state = self._dynamics.state
        if joints:
            self._publish_joints(now, state)
        if truth:
            x, y, phi = state.tip_pose
            self._truth_pub.publish(TipPose(
                header=self._header(now, PLANE_FRAME), pose=PlanarPose(x=x, y=y, phi=phi),
                valid=True, settled=not state.is_moving, holes_used=0, residual=0.0))
        if image:
            self._publish_image(now, state)

    def _publish_image(self, now: TimeMsg, state: ArmState) -> None:
        pixels = self._camera.render(state.tip_pose, tip_velocity=state.tip_velocity,
                                     rng=self._rng)
        height, width = pixels.shape
        self._image_pub.publish(Image(
            header=self._header(now, CAMERA_FRAME), height=height, width=width,
            encoding='mono8', is_bigendian=0, step=width, data=pixels.tobytes()))
        self._camera_info.header = self._header(now, CAMERA_FRAME)
        self._info_pub.publish(self._camera_info)

    def _make_camera_info(self) -> CameraInfo:
        """The camera's calibration (config/camera.yaml), not its true intrinsics."""
        return camera_info(self._calibration, self._header(self._now(), CAMERA_FRAME))

    def _now(self) -> TimeMsg:
        sec, nanosec = tick_time(self._tick, self._js_rate)
        return TimeMsg(sec=sec, nanosec=nanosec)

    @staticmethod
    def _header(now: TimeMsg, frame_id: str) -> Header:
        return Header(stamp=now, frame_id=frame_id)


def main(args: list[str] | None = None) -> None:
    run(SimNode, args)


if __name__ == '__main__':
    main()
