"""``flexarm_state_publisher``: the arm in rviz and Foxglove (a small robot_state_publisher).

Publishes the URDF (:mod:`.urdf_model`, from config/arm.yaml) latched on
``/robot_description``, with the ``<ros2_control>`` system on ``hardware_plugin`` that a
controller_manager reads from it (config/controllers.yaml configures its controllers); the
fixed frames (tool, tip camera and its optical frame) and ``arm_plane``, the frame of the
planar messages (:mod:`flexarm_core.frames`), latched on ``/tf_static``; on ``/tf`` the
four moving joints from ``/joint_states`` with the rigid model (:mod:`.chain`), and the frames
``tip_measured`` (``/tip_pose``, valid measurements only) and, in simulation, ``tip_true``
(``/sim/tip_pose_truth``) in ``base_link``. So ``tip_link`` is where the rigid model puts the
tool, ``tip_measured`` where the camera sees it, and the gap between them is the deflection.
The two tips are also published as ``geometry_msgs/PoseStamped`` on ``/scene/measured_tip`` and
``/scene/true_tip``.

Each stream is published at most ``publish_frequency`` times a second of wall-clock time (the
simulator publishes joint states at 100 Hz of sim time, 1000 a second at 10x real time), with
the stamp of the message it comes from, like robot_state_publisher's ``publish_frequency``:
joint states are taken raw and only the one published is parsed.

On demand (:mod:`flexarm_core.demand`): each input is subscribed only while what it makes
is watched — ``/joint_states`` while ``/tf`` has a subscriber, ``/tip_pose`` while ``/tf`` or
``/scene/measured_tip`` has one, ``/sim/tip_pose_truth`` while ``/tf`` or ``/scene/true_tip``
has one. Decision: watching the arm (rviz, Foxglove, a recorder) asks for the measured tip too,
so the vision node and the camera run while someone watches; an unwatched graph measures only
when a node measures.

Stamps: the node skips ``/clock`` (the simulator's 25 wake-ups a wall second): ``/tf`` and the
tips carry the stamp of their message, ``/diagnostics`` the graph's time (the newest ``/clock``
taken when they are published, :class:`flexarm_core.stamps.GraphTime`), ``/tf_static`` 0 (it is
published at start, before any data; tf2 holds a static transform at every time, and a
robot_state_publisher on sim time stamps it so before ``/clock``).

Health on ``/diagnostics`` (``flexarm_state_publisher: frames``): OK and idle while nobody
watches ``/tf``; then STALE until a ``/joint_states`` message comes, WARN when none came for
``JOINTS_STALE`` seconds or the last one lacked a joint, OK otherwise, with the /tf messages
published and the tips seen.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from functools import partial

from geometry_msgs.msg import PoseStamped, TransformStamped
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription
from sensor_msgs.msg import JointState
from std_msgs.msg import Header, String

from flexarm_core import topics
from flexarm_core.demand import Demand, on_matched
from flexarm_core.diagnostics import DiagnosticsPublisher
from flexarm_core.health_report import OK, STALE, WARN, Status, status
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.node_main import run
from flexarm_core.node_params import declare, declare_tree
from flexarm_core.scene_msgs import pose_stamped
from flexarm_core.stamps import GraphTime
from flexarm_description.chain import (
    BASE_FRAME,
    Transform,
    arm_joints,
    fixed_transforms,
    moving_transforms,
    planar_transform,
    plane_transform,
)
from flexarm_description.urdf_model import MOCK_HARDWARE, robot_description
from flexarm_msgs.msg import TipPose
from tf2_msgs.msg import TFMessage

MEASURED_FRAME = 'tip_measured'
TRUE_FRAME = 'tip_true'
JOINTS_STALE = 5.0      # [s, wall] without /joint_states: the frames are stale
NEWEST = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)   # /joint_states


class Throttle:
    """True at most ``frequency`` times a second (monotonic clock); ``frequency`` <= 0: always."""

    def __init__(self, frequency: float, clock: Callable[[], float] = time.monotonic) -> None:
        self._period = 1.0 / frequency if frequency > 0 else 0.0
        self._clock = clock
        self._next = float('-inf')

    def __call__(self) -> bool:
        now = self._clock()
        if now < self._next:
            return False
        self._next = now + self._period
        return True


def transform_msg(t: Transform, header: Header) -> TransformStamped:
    msg = TransformStamped(header=Header(stamp=header.stamp, frame_id=t.parent),
                           child_frame_id=t.child)
    msg.transform.translation.x, msg.transform.translation.y, msg.transform.translation.z = (
        t.translation)
    r = msg.transform.rotation
    r.x, r.y, r.z, r.w = t.rotation
    return msg


class StatePublisher(Node):
    def __init__(self) -> None:
        super().__init__('flexarm_state_publisher')
        arm = declare_tree(self, 'arm', 'config/arm.yaml')
        geometry = ArmGeometry.from_dict(arm)
        camera = declare_tree(self, 'camera', 'config/camera.yaml')
        frequency = declare(self, 'publish_frequency', 30.0,
                            '[Hz, wall clock] at most this many /tf (and tip pose) messages a '
                            'second per stream; <= 0: one per message received')
        hardware = declare(self, 'hardware_plugin', MOCK_HARDWARE,
                           'ros2_control hardware plugin of the URDF\'s <ros2_control> system; '
                           "'': no <ros2_control> block", read_only=True)
        self._joints = arm_joints(geometry, camera['offset'])
        latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
        self.create_publisher(String, topics.ROBOT_DESCRIPTION, latched).publish(
            String(data=robot_description(geometry, arm['inertia'], camera['offset'], hardware)))
        static = [*fixed_transforms(self._joints), plane_transform()]
        self.create_publisher(TFMessage, topics.TF_STATIC, latched).publish(TFMessage(
            transforms=[transform_msg(t, Header()) for t in static]))
        self._counts = {'tf': 0, 'measured': 0, 'true': 0}
        self._last_joints: float | None = None      # monotonic time of the last joint state
        self._joint_problem = ''
        self._throttles = {name: Throttle(frequency) for name in ('joints', 'measured', 'true')}
        tips = {'measured': (topics.TIP_POSE, topics.MEASURED_TIP, MEASURED_FRAME),
                'true': (topics.TIP_POSE_TRUTH, topics.TRUE_TIP, TRUE_FRAME)}
        # Each input by name: how to subscribe it, and its subscription while it is wanted.
        self._sources: dict[str, Callable[[], Subscription]] = {'joints': partial(
            self.create_subscription, JointState, topics.JOINT_STATES, self._on_joints, NEWEST,
            raw=True)}
        self._inputs: dict[str, Subscription] = {}
        demands = {name: Demand(partial(self._watch, name)) for name in ('joints', *tips)}
        for name, (source, target, frame) in tips.items():
            publisher = self.create_publisher(PoseStamped, target, 10, event_callbacks=(
                PublisherEventCallbacks(matched=on_matched(target, demands[name]))))
            self._sources[name] = partial(self.create_subscription, TipPose, source, partial(
                self._on_tip, name=name, publisher=publisher, frame=frame), 10)
        self._tf = self.create_publisher(TFMessage, topics.TF, 100, event_callbacks=(
            PublisherEventCallbacks(matched=on_matched(topics.TF, *demands.values()))))
        DiagnosticsPublisher(self, self._statuses, stamp=GraphTime(self).stamp)

    def _watch(self, name: str, wanted: bool) -> None:
        """Subscribe input ``name`` while what it makes is watched."""
        if wanted:
            self._inputs[name] = self._sources[name]()
        else:
            self.destroy_subscription(self._inputs.pop(name))

    def _on_joints(self, raw: bytes) -> None:
        self._last_joints = time.monotonic()
        if not self._throttles['joints']():
            return
        msg = deserialize_message(raw, JointState)
        positions = dict(zip(msg.name, msg.position, strict=False))
        try:
            transforms = moving_transforms(self._joints, positions)
        except ValueError as exc:
            self._joint_problem = f'/joint_states: {exc}'
            self.get_logger().warn(self._joint_problem, throttle_duration_sec=10.0)
            return
        self._joint_problem = ''
        self._tf.publish(TFMessage(transforms=[transform_msg(t, msg.header)
                                               for t in transforms]))
        self._counts['tf'] += 1

    def _on_tip(self, msg: TipPose, name: str, publisher, frame: str) -> None:
        if not msg.valid or not self._throttles[name]():
            return
        pose = (msg.pose.x, msg.pose.y, msg.pose.phi)
        self._tf.publish(TFMessage(transforms=[transform_msg(
            planar_transform(BASE_FRAME, frame, pose), msg.header)]))
        publisher.publish(pose_stamped(pose, msg.header.stamp))
        self._counts[name] += 1

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
