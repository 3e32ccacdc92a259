"""How the control nodes' moves reach the arm: the two command contracts of ros2_controllers.

* ``forward`` (forward_command_controller): the target as one position set-point on
  ``forward_position_controller/commands``. The controller passes it on as it is, so this
  suits controllers that plan the motion themselves: the simulator and the bridge's robot
  controller move each joint to it along their own speed- and acceleration-limited profile.
* ``trajectory`` (joint_trajectory_controller): the move as a ``trajectory_msgs/
  JointTrajectory`` on ``joint_trajectory_controller/joint_trajectory``, from where the arm is
  to the target along the fastest synchronized profile within the joints' speed and
  acceleration limits (config/arm.yaml ``arm.velocity``, ``arm.acceleration``;
  :mod:`flexarm_control.execution.shaped_move`), convolved with the input shaper
  ``motion.shaping`` (off, zv, zvd, ei; :mod:`flexarm_control.execution.shaping`) designed at
  the tip mode the robot description gives for the payload and the target's No.2 arm length
  (config/arm.yaml ``arm.tip_mode``, Table 6), so the move leaves the tip still; a point every
  ``trajectory_period`` seconds with positions, velocities and accelerations. Stamped 0: it
  starts when the controller gets it. A stop is one point where the stop was asked, at rest,
  as far off as braking from full speed and coming back takes within the limits: the
  controller splines to it from where the arm is and how fast it goes, so the arm ends where
  the caller was told it is held (as a set-point's profile does on the forward contract).

A set-point stream on the forward contract could carry a shaped reference only at the rate the
node can publish in the arm's time: a 20 ms wall poll is 0.2 s of simulated time at 10x, too
coarse for a 10 Hz mode. A shaped move therefore needs the trajectory contract, which the
controller interpolates in its own time; on the forward contract moves stay plain.

config/graph.yaml ``robot_settings`` chooses one per robot entry (``motion.joint_commands``).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Protocol

import numpy as np
from rclpy.duration import Duration
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flexarm_control.execution.shaped_move import MovePlanner, ShapedMove
from flexarm_core import topics
from flexarm_core.kinematics import JOINT_NAMES

KINDS = ('forward', 'trajectory')


class JointCommands(Protocol):
    def send(self, start: np.ndarray | None, target: np.ndarray) -> None:
        """Move from ``start`` (the joints now; None: unknown) to ``target``."""

    def stop(self, here: np.ndarray) -> None:
        """Stop the arm (at ``here``, the joints now)."""


class ForwardCommands:
    """One position set-point per move (forward_command_controller's contract)."""

    def __init__(self, node: Node) -> None:
        self._publisher = node.create_publisher(Float64MultiArray, topics.JOINT_COMMANDS, 10)

    def send(self, start: np.ndarray | None, target: np.ndarray) -> None:
        self._publisher.publish(Float64MultiArray(data=[float(v) for v in target]))

    def stop(self, here: np.ndarray) -> None:
        self.send(here, here)


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
        self._publisher = node.create_publisher(JointTrajectory, topics.JOINT_TRAJECTORY, 10)
        self._planner, self._payload = planner, payload

    def send(self, start: np.ndarray | None, target: np.ndarray) -> None:
        if start is None:                       # nothing known to plan from: go at once
            start = target
        self._publisher.publish(trajectory_message(
            self._planner.plan(start, target, self._payload())))

    def stop(self, here: np.ndarray) -> None:
        self._publisher.publish(trajectory_message(self._planner.stop(here)))


def joint_commands(node: Node, motion: Mapping[str, Any], arm: Mapping[str, Any],
                   payload: Callable[[], float]) -> JointCommands:
    """The command contract ``motion['joint_commands']`` names, with the arm's limits and
    tip mode (``payload()``: the load [kg] the arm carries now)."""
    kind = motion['joint_commands']
    planner = MovePlanner.from_dicts(motion, arm)     # checked whichever contract is used
    if kind == 'forward':
        return ForwardCommands(node)
    if kind == 'trajectory':
        return TrajectoryCommands(node, planner, payload)
    raise ValueError(f'motion.joint_commands {kind!r}: one of {", ".join(KINDS)}')
