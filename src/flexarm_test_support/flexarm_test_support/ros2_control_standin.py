"""A stand-in for a ros2_control arm and its camera driver, for the node-level tests of the
``ros2_control`` robot entry: no simulator node, no ``/clock``, everything on wall time.

What it offers is what a controller_manager with config/controllers.yaml and a camera driver
would: ``/joint_states`` (joint_state_broadcaster, 50 Hz), joint_trajectory_controller's
``joint_trajectory`` topic (a new trajectory replaces the one running, from where the reference
is and how fast it goes; the empty one holds the arm where it is) and its
``follow_joint_trajectory`` action, and the tip camera's ``Image`` and latched ``CameraInfo``
(5 Hz). Between the trajectory's points the reference is the cubic through their positions
and velocities (:class:`~flexarm_core.joint_trajectory.SampledTrajectory`, the controller's
spline without accelerations); the joints follow it with the hardware's own tracking error, a
first-order lag of ``TRACKING_LAG`` s over the wall time that passed (a starved process is
late, the arm it stands for is not). The tip is the simulated real arm's deflected pose at the
joints (the simulator's plant, config/sim.yaml), seen by an ideal camera.

The action as joint_trajectory_controller (Jazzy) serves it: a goal replaces the running one,
which ends ABORTED with INVALID_GOAL ("Current goal preempted by new incoming action."); the
goal's tolerances override config/controllers.yaml's ``constraints`` (0: the configured one,
-1: none); while the trajectory runs, a joint off the reference by more than its path tolerance
aborts the goal (PATH_TOLERANCE_VIOLATED) and holds the arm; after its end, the joints within
the goal tolerance and slower than ``stopped_velocity_tolerance`` succeed it, and not so
``goal_time`` after the end aborts it (GOAL_TOLERANCE_VIOLATED); a cancel holds the arm. No
feedback is published (flexarm reads none).

Hardware limits (parameters ``arm.lower`` and ``arm.upper``, [rad, m, rad, rad], as config/
arm.yaml gives them): a goal whose trajectory leaves them is refused before anything moves, as a
controller that checks its joints' limits does. A ROS 2 action's rejection carries no reason,
so it accepts the goal and aborts it at once with INVALID_GOAL and an ``error_string`` naming
the joint and its limit; the running goal goes on. A test narrows them to have goals refused.
Its description served: like Jazzy's controller_manager it takes the URDF from
``/robot_description`` (latched) and brings nothing up before it has one whose
``<ros2_control>`` system commands every joint of config/arm.yaml (flexarm's state publisher
serves it; the spawner's controllers come up then): a recipe that starts the controller side
first works only if the description reaches it.

Run as a node process::

    python -m flexarm_test_support.ros2_control_standin --ros-args ...
"""
from __future__ import annotations

import math
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np
from action_msgs.msg import GoalStatus
from rclpy.action import ActionServer, CancelResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile
from rclpy.task import Future
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header, String
from trajectory_msgs.msg import JointTrajectory

from control_msgs.action import FollowJointTrajectory
from flexarm_core import topics
from flexarm_core.frames import BASE_FRAME
from flexarm_core.joint_trajectory import SampledTrajectory
from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry
from flexarm_core.params import config_path, load_config, load_node_params
from flexarm_core.ros.node_main import run
from flexarm_core.ros.node_params import declare
from flexarm_core.ros.trajectory_message import trajectory_from
from flexarm_sim.camera import CameraRenderer
from flexarm_sim.plant import configured_plant
from flexarm_vision.camera_info import camera_info
from flexarm_vision.camera_model import CameraModel

RATE = 50.0            # [Hz, wall] of /joint_states and the joints' update
CAMERA_EVERY = 10      # updates per camera frame: 5 Hz
TRACKING_LAG = 0.05    # [s] of the joints behind the reference
CAMERA_FRAME = 'tip_camera_optical_frame'
START = np.array([0.0, 0.6, -0.5, -0.5])
Result = FollowJointTrajectory.Result
PREEMPTED = 'Current goal preempted by new incoming action.'


def resolved(configured: float, given: float) -> float:
    """A goal's tolerance over the configured one: 0 keeps it, -1 erases it (0: unchecked)."""
    return configured if given == 0 else 0.0 if given == -1 else given


@dataclass
class Goal:
    """The goal the trajectory running now belongs to."""

    handle: ServerGoalHandle
    path: np.ndarray          # (4,) position tolerances while it runs (0: unchecked)
    goal: np.ndarray          # (4,) position tolerances at its end
    goal_time: float          # [s] after its end to come within them (0: for ever)
    ended: Future             # its result and status, once it ends


class Ros2ControlStandIn(Node):

    def __init__(self) -> None:
        super().__init__('ros2_control_standin')
        config = load_config('arm.yaml', 'camera.yaml')
        geometry = ArmGeometry.from_dict(config['arm'])
        self._plant = configured_plant(geometry)
        self._camera = CameraRenderer.from_dict(config)
        self._info = camera_info(CameraModel.from_dict(config['camera']).intrinsics,
                                 Header(frame_id=CAMERA_FRAME))
        self._rng = np.random.default_rng(5)
        self._lower = np.array(declare(self, 'arm.lower', 'config/arm.yaml'))
        self._upper = np.array(declare(self, 'arm.upper', 'config/arm.yaml'))
        constraints = load_node_params(config_path('controllers.yaml'),
                                       'joint_trajectory_controller')['constraints']
        self._path = np.array([constraints[n]['trajectory'] for n in JOINT_NAMES])
        self._goal_tolerance = np.array([constraints[n]['goal'] for n in JOINT_NAMES])
        self._goal_time = float(constraints['goal_time'])
        self._stopped = float(constraints['stopped_velocity_tolerance'])
        self._active: Goal | None = None
        self._q = START.copy()
        self._speed = np.zeros(4)
        self._last = time.monotonic()
        self._trajectory: tuple[SampledTrajectory, float] | None = None   # and when it came
        self._held = START.copy()         # the reference without a trajectory
        self._tip = self._plant.pose(self._q)
        self._ticks = 0
        latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
        self._description = self.create_subscription(
            String, topics.ROBOT_DESCRIPTION, self._on_description, latched)

    def _on_description(self, msg: String) -> None:
        """The controllers come up once the description names every joint in its
        ``<ros2_control>`` system (as spawned by ``spawner``)."""
        system = ET.fromstring(msg.data).find('ros2_control')
        named = set() if system is None else {j.get('name') for j in system.iter('joint')}
        if not set(JOINT_NAMES) <= named:
            self.get_logger().error(f'/robot_description has no <ros2_control> system with '
                                    f'{JOINT_NAMES}: no controller started')
            return
        self.destroy_subscription(self._description)
        latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
        self._joints = self.create_publisher(JointState, topics.JOINT_STATES, 10)
        self._images = self.create_publisher(Image, topics.CAMERA_IMAGE, 5)
        self._infos = self.create_publisher(CameraInfo, topics.CAMERA_INFO, latched)
        self.create_subscription(JointTrajectory, topics.JOINT_TRAJECTORY, self._on_trajectory,
                                 10)
        self._server = ActionServer(self, FollowJointTrajectory, topics.FOLLOW_JOINT_TRAJECTORY,
                                    self._execute,
                                    cancel_callback=lambda _: CancelResponse.ACCEPT)
        self.create_timer(1.0 / RATE, self._update)
        self.get_logger().info('robot description received: controllers active')

    def _reference_now(self) -> tuple[np.ndarray, np.ndarray]:
        if self._trajectory is None:
            return self._held, np.zeros_like(self._held)
        trajectory, since = self._trajectory
        return trajectory.at(time.monotonic() - since)

    def _on_trajectory(self, msg: JointTrajectory) -> None:
        position, velocity = self._reference_now()
        if msg.points:
            trajectory = trajectory_from(msg).starting(position, velocity)
            self._trajectory = (trajectory, time.monotonic())
        else:
            self._hold()

    def _hold(self) -> None:
        self._trajectory, self._held = None, self._q.copy()

    def _beyond_limits(self, msg: JointTrajectory) -> str:
        """Why the trajectory leaves the hardware's limits ('' if it does not)."""
        for point in trajectory_from(msg).positions:
            for name, value, low, high in zip(JOINT_NAMES, point, self._lower, self._upper):
                if not low <= value <= high:
                    return (f'{name} position {value:.4f} is beyond the hardware limits '
                            f'[{low:.4f}, {high:.4f}]')
        return ''

    def _end(self, status: int, code: int, text: str) -> None:
        """End the active goal with ``status`` and its result."""
        active, self._active = self._active, None
        if active is not None:
            active.ended.set_result((status, Result(error_code=code, error_string=text)))

    async def _execute(self, handle: ServerGoalHandle) -> FollowJointTrajectory.Result:
        goal: FollowJointTrajectory.Goal = handle.request
        refused = self._beyond_limits(goal.trajectory)
        if refused or not goal.trajectory.points:
            handle.abort()
            return Result(error_code=Result.INVALID_GOAL,
                          error_string=refused or 'Empty trajectory received.')
        self._end(GoalStatus.STATUS_ABORTED, Result.INVALID_GOAL, PREEMPTED)
        path, goal_tolerance = self._path.copy(), self._goal_tolerance.copy()
        names = list(JOINT_NAMES)
        for given in goal.path_tolerance:
            path[names.index(given.name)] = resolved(path[names.index(given.name)],
                                                     given.position)
        for given in goal.goal_tolerance:
            goal_tolerance[names.index(given.name)] = resolved(
                goal_tolerance[names.index(given.name)], given.position)
        duration = goal.goal_time_tolerance
        self._on_trajectory(goal.trajectory)
        self._active = Goal(handle, path, goal_tolerance,
                            resolved(self._goal_time, duration.sec + 1e-9 * duration.nanosec),
                            Future())
        status, result = await self._active.ended
        if status == GoalStatus.STATUS_SUCCEEDED:
            handle.succeed()
        elif status == GoalStatus.STATUS_CANCELED:
            handle.canceled()
        else:
            handle.abort()
        return result

    def _check(self) -> None:
        """The active goal against its tolerances (joint_trajectory_controller's update)."""
        active = self._active
        if active is None or self._trajectory is None:
            return
        if active.handle.is_cancel_requested:
            self._hold()
            self._end(GoalStatus.STATUS_CANCELED, Result.SUCCESSFUL, '')
            return
        trajectory, since = self._trajectory
        late = time.monotonic() - since - trajectory.duration
        error = np.abs(self._reference_now()[0] - self._q)
        if late < 0:
            if np.any((active.path > 0) & (error > active.path)):
                self._hold()
                self._end(GoalStatus.STATUS_ABORTED, Result.PATH_TOLERANCE_VIOLATED,
                          'Aborted due to path tolerance violation')
            return
        if (np.all((active.goal <= 0) | (error <= active.goal))
                and np.all(np.abs(self._speed) <= self._stopped)):
            self._end(GoalStatus.STATUS_SUCCEEDED, Result.SUCCESSFUL, 'Goal successfully reached!')
        elif active.goal_time > 0 and late > active.goal_time:
            self._hold()
            self._end(GoalStatus.STATUS_ABORTED, Result.GOAL_TOLERANCE_VIOLATED,
                      f'Aborted due to goal_time_tolerance exceeding by {late:.6f} seconds')

    def _update(self) -> None:
        now = time.monotonic()
        dt, self._last = max(now - self._last, 1e-6), now
        before = self._q.copy()
        self._q += (self._reference_now()[0] - self._q) * (1.0 - math.exp(-dt / TRACKING_LAG))
        self._speed = (self._q - before) / dt
        self._check()
        stamp = self.get_clock().now().to_msg()
        self._joints.publish(JointState(
            header=Header(stamp=stamp, frame_id=BASE_FRAME), name=list(JOINT_NAMES),
            position=self._q.tolist(), velocity=self._speed.tolist()))
        self._ticks += 1
        if self._ticks % CAMERA_EVERY:
            return
        tip = self._plant.pose(self._q)
        speed = (tip - self._tip) / (CAMERA_EVERY / RATE)
        self._tip = tip
        pixels = self._camera.render(tip, tip_velocity=speed, rng=self._rng)
        height, width = pixels.shape
        header = Header(stamp=stamp, frame_id=CAMERA_FRAME)
        self._images.publish(Image(header=header, height=height, width=width, encoding='mono8',
                                   is_bigendian=0, step=width, data=pixels.tobytes()))
        self._info.header = header
        self._infos.publish(self._info)


def main(args: list[str] | None = None) -> None:
    run(Ros2ControlStandIn, args)


if __name__ == '__main__':
    main()
