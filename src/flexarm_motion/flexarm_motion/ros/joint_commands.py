"""How the control nodes' moves reach the arm: the command contracts of ros2_controllers.

* ``forward`` (forward_command_controller): the target as one position set-point on
  ``forward_position_controller/commands``. The controller passes it on as it is, so this
  suits controllers that plan the motion themselves: the simulator and the bridge's robot
  controller move each joint to it along their own speed- and acceleration-limited profile.
* ``trajectory`` (joint_trajectory_controller): the move as a ``trajectory_msgs/
  JointTrajectory`` on ``joint_trajectory_controller/joint_trajectory``, from where the arm is
  to the target along the fastest synchronized profile within the joints' speed and
  acceleration limits (config/arm.yaml ``arm.velocity``, ``arm.acceleration``;
  :mod:`flexarm_motion.shaped_move`), convolved with the input shaper
  ``motion.shaping`` (off, zv, zvd, ei; :mod:`flexarm_motion.shaping`) designed at
  the tip mode the robot description gives for the payload and the target's No.2 arm length
  (config/arm.yaml ``arm.tip_mode``, Table 6), so the move leaves the tip still; a point every
  ``trajectory_period`` seconds with positions, velocities and accelerations. Stamped 0: it
  starts when the controller gets it. A stop is one point where the stop was asked, at rest,
  as far off as braking from full speed and coming back takes within the limits: the
  controller splines to it from where the arm is and how fast it goes, so the arm ends where
  the caller was told it is held (as a set-point's profile does on the forward contract).

* ``follow_joint_trajectory`` (joint_trajectory_controller, as MoveIt drives it): the same
  trajectory as a ``control_msgs/FollowJointTrajectory`` goal on
  ``joint_trajectory_controller/follow_joint_trajectory``, with the path and goal tolerances and
  the goal time of :mod:`flexarm_motion.ros.trajectory_goal`. The controller answers:
  a goal it rejects, or one it aborts (a path or goal tolerance violated, an invalid goal, ...),
  is the move's :attr:`~JointCommands.problem` in its words, which ends the move's wait at once
  (:meth:`~flexarm_motion.ros.arm_interface.ArmInterface.move`). A goal flexarm's own next move
  or stop replaced (the controller aborts it as preempted) is no failure: only the newest
  goal's answer counts.

A set-point stream on the forward contract could carry a shaped reference only at the rate the
node can publish in the arm's time: a 20 ms wall poll is 0.2 s of simulated time at 10x, too
coarse for a 10 Hz mode. A shaped move therefore needs the trajectory contract, which the
controller interpolates in its own time; on the forward contract moves stay plain.

config/graph.yaml ``robot_settings`` chooses one per robot entry (``motion.joint_commands``).
On the contracts without an answer, arrival is seen only in ``/joint_states``. A move's command
goes out on them only once the controller's subscription has matched the publisher (waited for
as the action contract waits for its server): a command published before, a moment after the
node started, is lost (volatile), and the move would wait out its time limit for an arm that
never got it. No controller within the wait: the move's :attr:`~JointCommands.problem`. A stop
is sent at once: a controller that never listened has nothing to stop.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from typing import Any, Protocol

import numpy as np
from rclpy.action import ActionClient
from rclpy.action.client import ClientGoalHandle
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.task import Future
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from control_msgs.action import FollowJointTrajectory
from flexarm_core import liveness, topics
from flexarm_core.kinematics import JOINT_NAMES
from flexarm_motion.ros.trajectory_goal import (
    TrajectoryTolerances,
    failure,
    goal_message,
    rejection,
)
from flexarm_motion.shaped_move import MovePlanner, ShapedMove

KINDS = ('forward', 'trajectory', 'follow_joint_trajectory')
# [s, wall] a move waits for the controller's action server or subscription to be discovered
# (times the liveness factor): it is there when the graph is; discovery takes a moment on a
# loaded machine.
SERVER_WAIT = 5.0
_POLL = 0.01    # [s] how often a move looks for the controller's subscription


class JointCommands(Protocol):
    def send(self, start: np.ndarray | None, target: np.ndarray) -> None:
        """Move from ``start`` (the joints now; None: unknown) to ``target``."""

    def stop(self, here: np.ndarray) -> None:
        """Stop the arm (at ``here``, the joints now)."""

    @property
    def problem(self) -> str:
        """Why the last move fell short of its target: no controller listened, or the
        controller ended it, in its words ('' while it runs, once it succeeded, and on a
        contract whose controller does not answer)."""


def unheard(node: Node, publisher: Publisher) -> str:
    """'' once a subscription matched ``publisher`` (waiting up to :data:`SERVER_WAIT`,
    liveness-scaled, or until the node shuts down), else why the command cannot be sent."""
    deadline = time.monotonic() + liveness.limit(SERVER_WAIT)
    while not publisher.get_subscription_count():
        if time.monotonic() > deadline or not node.context.ok():
            return (f'no controller subscribes to {publisher.topic_name}: is it running? '
                    'Nothing was commanded')
        time.sleep(_POLL)
    return ''


class ForwardCommands:
    """One position set-point per move (forward_command_controller's contract)."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._publisher = node.create_publisher(Float64MultiArray, topics.JOINT_COMMANDS, 10)
        self.problem = ''   # no controller listened to the last move; it does not answer

    def send(self, start: np.ndarray | None, target: np.ndarray) -> None:
        self.problem = unheard(self._node, self._publisher)
        if not self.problem:
            self._set_point(target)

    def stop(self, here: np.ndarray) -> None:
        self._set_point(here)

    def _set_point(self, q: np.ndarray) -> None:
        self._publisher.publish(Float64MultiArray(data=[float(v) for v in q]))


def trajectory_message(move: ShapedMove) -> JointTrajectory:
    """``move`` as joint_trajectory_controller takes it: its samples after the start."""
    return JointTrajectory(joint_names=list(JOINT_NAMES), points=[
        JointTrajectoryPoint(positions=p.tolist(), velocities=v.tolist(),
                             accelerations=a.tolist(),
                             time_from_start=Duration(nanoseconds=round(t * 1e9)).to_msg())
        for t, p, v, a in zip(move.times[1:], move.positions[1:], move.velocities[1:],
                              move.accelerations[1:])])


class TrajectoryCommands:
    """A shaped trajectory within the joint limits per move (joint_trajectory_controller's
    contract); ``payload()``: the load [kg] the arm carries now."""

    def __init__(self, node: Node, planner: MovePlanner, payload: Callable[[], float]) -> None:
        self._node = node
        self._publisher = node.create_publisher(JointTrajectory, topics.JOINT_TRAJECTORY, 10)
        self._planner, self._payload = planner, payload
        self.problem = ''   # no controller listened to the last move; it does not answer

    def send(self, start: np.ndarray | None, target: np.ndarray) -> None:
        self.problem = unheard(self._node, self._publisher)
        if self.problem:
            return
        if start is None:                       # nothing known to plan from: go at once
            start = target
        self._publisher.publish(trajectory_message(
            self._planner.plan(start, target, self._payload())))

    def stop(self, here: np.ndarray) -> None:
        self._publisher.publish(trajectory_message(self._planner.stop(here)))


class FollowTrajectoryCommands:
    """The shaped trajectory of each move as a FollowJointTrajectory goal, with the arm's
    tolerances (joint_trajectory_controller's action); ``payload()``: the load [kg] the arm
    carries now.

    A stop is a goal of its own, the topic contract's stop trajectory, not a cancel: canceled,
    joint_trajectory_controller holds the arm where its state is at that instant, a step in
    the commanded velocity of a moving arm (the ringing shaping avoids), and not where the
    caller was told the arm is held; the one-point goal brakes within the joints' limits to
    that point. It preempts the running goal, as every new move does.
    """

    def __init__(self, node: Node, planner: MovePlanner, payload: Callable[[], float],
                 tolerances: TrajectoryTolerances) -> None:
        self._client = ActionClient(node, FollowJointTrajectory, topics.FOLLOW_JOINT_TRAJECTORY,
                                    callback_group=MutuallyExclusiveCallbackGroup())
        self._planner, self._payload, self._tolerances = planner, payload, tolerances
        self._lock = threading.Lock()
        self._sent = 0          # goals sent; only the newest one's answer counts
        self._problem = ''

    @property
    def problem(self) -> str:
        with self._lock:
            return self._problem

    def send(self, start: np.ndarray | None, target: np.ndarray) -> None:
        if start is None:                       # nothing known to plan from: go at once
            start = target
        self._send(self._planner.plan(start, target, self._payload()))

    def stop(self, here: np.ndarray) -> None:
        self._send(self._planner.stop(here))

    def _send(self, move: ShapedMove) -> None:
        with self._lock:
            self._sent += 1
            number, self._problem = self._sent, ''
        if not self._client.server_is_ready():
            self._client.wait_for_server(liveness.limit(SERVER_WAIT))
        if not self._client.server_is_ready():
            self._answer(number, f'no {topics.FOLLOW_JOINT_TRAJECTORY} action server: is '
                         'joint_trajectory_controller loaded and active?')
            return
        sent = self._client.send_goal_async(goal_message(trajectory_message(move),
                                                         self._tolerances))
        sent.add_done_callback(lambda future: self._on_response(number, future))

    def _answer(self, number: int, problem: str) -> None:
        with self._lock:
            if number == self._sent:            # an older goal's answer: replaced, no failure
                self._problem = problem

    def _on_response(self, number: int, future: Future) -> None:
        handle: ClientGoalHandle | None = future.result()
        if handle is None or not handle.accepted:
            self._answer(number, rejection())
            return
        handle.get_result_async().add_done_callback(
            lambda done: self._on_result(number, done))

    def _on_result(self, number: int, future: Future) -> None:
        response = future.result()
        if response is not None:
            self._answer(number, failure(response.status, response.result.error_code,
                                         response.result.error_string))


def joint_commands(node: Node, motion: Mapping[str, Any], arm: Mapping[str, Any],
                   payload: Callable[[], float]) -> JointCommands:
    """The command contract ``motion['joint_commands']`` names, with the arm's limits, tip
    mode and tolerances (``payload()``: the load [kg] the arm carries now)."""
    kind = motion['joint_commands']
    planner = MovePlanner.from_dicts(motion, arm)     # checked whichever contract is used
    tolerances = TrajectoryTolerances.from_dicts(arm, motion)
    if kind == 'forward':
        return ForwardCommands(node)
    if kind == 'trajectory':
        return TrajectoryCommands(node, planner, payload)
    if kind == 'follow_joint_trajectory':
        return FollowTrajectoryCommands(node, planner, payload, tolerances)
    raise ValueError(f'motion.joint_commands {kind!r}: one of {", ".join(KINDS)}')
