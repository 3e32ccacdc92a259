"""``flexarm_state_publisher``: the arm in rviz and Foxglove (a small robot_state_publisher).

Publishes the URDF (:mod:`flexarm_description.urdf_model`, from config/arm.yaml) latched on
``/robot_description``, the fixed frames and ``arm_plane`` latched on ``/tf_static``, and on
``/tf`` the four moving joints from ``/joint_states`` through the rigid chain
(:mod:`flexarm_description.chain`) and the tips ``tip_measured`` (``/tip_pose``) and
``tip_true`` (``/sim/tip_pose_truth``), also as poses on ``/scene/measured_tip`` and
``/scene/true_tip``. Each input is subscribed only while what it makes is watched, and taken
raw (:class:`flexarm_core.ros.taken.Taken`) at most ``publish_frequency`` times a wall second.

Explained in docs/nodes.md#the-state-publisher-flexarm_state_publisher.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from functools import partial

from geometry_msgs.msg import PoseStamped
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription
from rclpy.timer import Timer
from sensor_msgs.msg import JointState
from std_msgs.msg import Header, String

from flexarm_core import topics
from flexarm_core.health_report import OK, STALE, WARN, Status, status
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.ros.diagnostics import DiagnosticsPublisher
from flexarm_core.ros.node_main import run
from flexarm_core.ros.node_params import declare, declare_tree
from flexarm_core.ros.scene_msgs import pose_stamped
from flexarm_core.ros.stamps import GraphTime
from flexarm_core.ros.taken import Taken, take
from flexarm_description.chain import (
    BASE_FRAME,
    arm_joints,
    fixed_transforms,
    moving_transforms,
    planar_transform,
    plane_transform,
)
from flexarm_description.tf_message import transform_msg
from flexarm_description.urdf_model import published_description
from flexarm_msgs.msg import TipPose
from tf2_msgs.msg import TFMessage

MEASURED_FRAME = 'tip_measured'
TRUE_FRAME = 'tip_true'
JOINTS_STALE = 5.0      # [s, wall] without /joint_states: the frames are stale
RECHECK = 0.2           # [s, wall] between looks at subscribers whose node is not known yet
NEWEST = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)   # joints, truth
MEASURED = 10           # /tip_pose frames kept between two timer ticks (50 a second at 10x)
UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'     # rmw's name of a node it does not know yet


def wanted_inputs(subscribers: dict[str, int], recording: dict[str, int]) -> dict[str, bool]:
    """Which inputs to subscribe (docs/nodes.md), from the subscriber count of each output
    (``/tf``, ``/scene/measured_tip``, ``/scene/true_tip``) and how many of them are
    recorders'."""
    def viewers(output: str) -> int:
        return subscribers.get(output, 0) - recording.get(output, 0)

    return {'joints': subscribers.get(topics.TF, 0) > 0,
            'true': subscribers.get(topics.TF, 0) + subscribers.get(topics.TRUE_TIP, 0) > 0,
            'measured': viewers(topics.TF) + viewers(topics.MEASURED_TIP) > 0}


def not_viewers(count: int, names: list[str], recorders: set[str]) -> int:
    """How many of an output's ``count`` subscribers (of node ``names``, as the graph knows
    them so far) are not viewers: recorders, and those whose node is not known yet (module
    docstring)."""
    known = [name for name in names if name != UNKNOWN_NODE]
    return sum(name in recorders for name in known) + max(0, count - len(known))


class StatePublisher(Node):
    def __init__(self) -> None:
        super().__init__('flexarm_state_publisher')
        arm = declare_tree(self, 'arm', 'config/arm.yaml')
        geometry = ArmGeometry.from_dict(arm)
        camera = declare_tree(self, 'camera', 'config/camera.yaml')
        frequency = declare(self, 'publish_frequency', 'config/description.yaml')
        self._recorders = set(declare(self, 'recorders', 'config/description.yaml'))
        hardware = declare(self, 'hardware_plugin', 'config/description.yaml', read_only=True)
        driver = declare(self, 'hardware_parameters', 'config/description.yaml', read_only=True)
        self._joints = arm_joints(geometry, camera['offset'])
        latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
        self.create_publisher(String, topics.ROBOT_DESCRIPTION, latched).publish(String(
            data=published_description({'arm': arm, 'camera': camera,
                                        'hardware_plugin': hardware,
                                        'hardware_parameters': driver})))
        static = [*fixed_transforms(self._joints), plane_transform()]
        self.create_publisher(TFMessage, topics.TF_STATIC, latched).publish(TFMessage(
            transforms=[transform_msg(t, Header()) for t in static]))
        self._counts = {'tf': 0, 'measured': 0, 'true': 0}
        self._last_joints: float | None = None      # monotonic time of the last joint state
        self._joint_problem = ''
        self._period = 1.0 / frequency if frequency > 0 else 0.0
        self._taken = Taken() if self._period else None
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._tick: Timer | None = None             # takes the inputs, while any is subscribed
        self._recheck: Timer | None = None          # while a subscriber's node is unknown
        self._subscribers: dict[str, int] = {}      # output: matched subscriptions
        tips = {'measured': (topics.TIP_POSE, topics.MEASURED_TIP, MEASURED_FRAME, MEASURED),
                'true': (topics.TIP_POSE_TRUTH, topics.TRUE_TIP, TRUE_FRAME, NEWEST)}
        # Each input by name: how to subscribe it, what handles a message (raw), and its
        # subscription while it is wanted.
        self._sources: dict[str, tuple[type, str, QoSProfile | int]] = {
            'joints': (JointState, topics.JOINT_STATES, NEWEST)}
        self._handlers: dict[str, Callable[[bytes], bool]] = {'joints': self._on_joints}
        self._inputs: dict[str, Subscription] = {}
        for name, (source, target, frame, qos) in tips.items():
            publisher = self.create_publisher(PoseStamped, target, 10, event_callbacks=(
                PublisherEventCallbacks(matched=partial(self._matched, target))))
            self._sources[name] = (TipPose, source, qos)
            self._handlers[name] = partial(self._on_tip, name=name, publisher=publisher,
                                           frame=frame)
        self._tf = self.create_publisher(TFMessage, topics.TF, 100, event_callbacks=(
            PublisherEventCallbacks(matched=partial(self._matched, topics.TF))))
        DiagnosticsPublisher(self, self._statuses, stamp=GraphTime(self).stamp)

    # --- demand -------------------------------------------------------------------------------
    def _matched(self, output: str, info) -> None:
        self._subscribers[output] = info.current_count
        self._decide()

    def _decide(self) -> None:
        """Subscribe the inputs that are wanted now, unsubscribe the others (module
        docstring); look again soon while a subscriber's node is not known yet."""
        recording, unknown = {}, False
        for output, count in self._subscribers.items():
            if output == topics.TRUE_TIP or not count:
                continue
            names = [info.node_name for info in self.get_subscriptions_info_by_topic(output)]
            recording[output] = not_viewers(count, names, self._recorders)
            unknown |= len(names) < count or UNKNOWN_NODE in names
        for name, wanted in wanted_inputs(self._subscribers, recording).items():
            if wanted and name not in self._inputs:
                message_type, topic, qos = self._sources[name]
                handler = self._handlers[name]
                self._inputs[name] = self.create_subscription(
                    message_type, topic, handler if self._taken is None else lambda _: None,
                    qos, raw=True, callback_group=self._taken)
            elif not wanted and name in self._inputs:
                self.destroy_subscription(self._inputs.pop(name))
        self._tick = self._timer(self._tick, self._taken is not None and bool(self._inputs),
                                 self._period, self._take_inputs)
        self._recheck = self._timer(self._recheck, unknown, RECHECK, self._decide)

    def _timer(self, timer: Timer | None, wanted: bool, period: float,
               callback: Callable[[], None]) -> Timer | None:
        """The timer running while wanted (made or destroyed as need be)."""
        if wanted and timer is None:
            return self.create_timer(period, callback, clock=self._steady)
        if not wanted and timer is not None:
            self.destroy_timer(timer)
            return None
        return timer

    # --- inputs -------------------------------------------------------------------------------
    def _take_inputs(self) -> None:
        """Publish the newest message of each input that came since the last tick (of the
        measured tip the newest valid one)."""
        for name, subscription in list(self._inputs.items()):
            taken = []
            while (raw := take(subscription)) is not None:
                taken.append(raw)
            for raw in reversed(taken):
                if self._handlers[name](raw):
                    break

    def _on_joints(self, raw: bytes) -> bool:
        self._last_joints = time.monotonic()
        msg = deserialize_message(raw, JointState)
        positions = dict(zip(msg.name, msg.position, strict=False))
        try:
            transforms = moving_transforms(self._joints, positions)
        except ValueError as exc:
            self._joint_problem = f'/joint_states: {exc}'
            self.get_logger().warn(self._joint_problem, throttle_duration_sec=10.0)
            return True
        self._joint_problem = ''
        self._tf.publish(TFMessage(transforms=[transform_msg(t, msg.header)
                                               for t in transforms]))
        self._counts['tf'] += 1
        return True

    def _on_tip(self, raw: bytes, name: str, publisher, frame: str) -> bool:
        """Publish a valid tip pose (the frame and the pose); whether it was valid."""
        msg = deserialize_message(raw, TipPose)
        if not msg.valid:
            return False
        pose = (msg.pose.x, msg.pose.y, msg.pose.phi)
        self._tf.publish(TFMessage(transforms=[transform_msg(
            planar_transform(BASE_FRAME, frame, pose), msg.header)]))
        if publisher.get_subscription_count():      # else /tf asked for it: made for nobody
            publisher.publish(pose_stamped(pose, msg.header.stamp))
        self._counts[name] += 1
        return True

    def _statuses(self) -> list[Status]:
        values = {'joint state age [s]': 'none yet' if self._last_joints is None else
                  round(time.monotonic() - self._last_joints, 2),
                  '/tf joint messages': self._counts['tf'],
                  'measured tips': self._counts['measured'], 'true tips': self._counts['true']}
        name = self.get_name()
        if 'joints' not in self._inputs:
            return [status(name, 'frames', OK, 'idle: no subscriber of /tf', values)]
        if self._last_joints is None:
            return [status(name, 'frames', STALE, 'no /joint_states yet', values)]
        if time.monotonic() - self._last_joints > JOINTS_STALE:
            return [status(name, 'frames', WARN, f'no /joint_states for {JOINTS_STALE:g} s',
                           values)]
        if self._joint_problem:
            return [status(name, 'frames', WARN, self._joint_problem, values)]
        return [status(name, 'frames', OK, 'following /joint_states', values)]


def main(args: list[str] | None = None) -> None:
    run(StatePublisher, args)


if __name__ == '__main__':
    main()
