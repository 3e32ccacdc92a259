"""How the control nodes' moves reach the arm: the two command contracts of ros2_controllers.

* ``forward`` (forward_command_controller): the target as one position set-point on
  ``forward_position_controller/commands``. The controller passes it on as it is, so this
  suits controllers that plan the motion themselves: the simulator and the bridge's robot
  controller move each joint to it along their own speed- and acceleration-limited profile.
* ``trajectory`` (joint_trajectory_controller): the move as a ``trajectory_msgs/
  JointTrajectory`` on ``joint_trajectory_controller/joint_trajectory``, from where the arm is
  to the target along the fastest synchronized profile within the joints' speed and
  acceleration limits (config/arm.yaml ``arm.velocity``, ``arm.acceleration``;
  :mod:`flexarm_control.execution.shaped_move`), a point every ``trajectory_period`` seconds
  with positions, velocities and accelerations. Stamped 0: it starts when the controller gets
  it. A stop is the empty trajectory, on which the controller holds where the arm is.

config/graph.yaml ``robot_settings`` chooses one per robot entry (``motion.joint_commands``).
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np
from builtin_interfaces.msg import Duration
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flexarm_control.execution.shaped_move import ShapedMove, plan_profile, shape_move
from flexarm_control.execution.shaping import Shaper
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


def duration(seconds: float) -> Duration:
    nanoseconds = round(seconds * 1e9)
    return Duration(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def trajectory_message(move: ShapedMove) -> JointTrajectory:
    """``move`` as joint_trajectory_controller takes it: its samples after the start."""
    return JointTrajectory(joint_names=list(JOINT_NAMES), points=[
        JointTrajectoryPoint(positions=p.tolist(), velocities=v.tolist(),
                             accelerations=a.tolist(), time_from_start=duration(t))
        for t, p, v, a in zip(move.times[1:], move.positions[1:], move.velocities[1:],
                              move.accelerations[1:])])


class TrajectoryCommands:
    """A trajectory within the joint limits per move (joint_trajectory_controller's contract)."""

    def __init__(self, node: Node, velocity: np.ndarray, acceleration: np.ndarray,
                 period: float) -> None:
        self._publisher = node.create_publisher(JointTrajectory, topics.JOINT_TRAJECTORY, 10)
        self._velocity, self._acceleration = velocity, acceleration
        self._period = period
        self._plain = Shaper.design('off', 1.0, 0.0)

    def send(self, start: np.ndarray | None, target: np.ndarray) -> None:
        if start is None:                       # nothing known to plan from: go at once
            start = target
        profile = plan_profile(start, target, self._velocity, self._acceleration)
        move = shape_move(profile, self._plain, self._period)
        if move.times.size < 2:                 # already there: one point, to hold it
            move = ShapedMove(np.array([0.0, self._period]), np.array([target, target]),
                              np.zeros((2, target.size)), np.zeros((2, target.size)),
                              self._plain)
        self._publisher.publish(trajectory_message(move))

    def stop(self, here: np.ndarray) -> None:
        self._publisher.publish(JointTrajectory(joint_names=list(JOINT_NAMES)))


def joint_commands(node: Node, motion: Mapping[str, Any], arm: Mapping[str, Any]
                   ) -> JointCommands:
    """The command contract ``motion['joint_commands']`` names, with the arm's limits."""
    kind = motion['joint_commands']
    if kind == 'forward':
        return ForwardCommands(node)
    if kind == 'trajectory':
        return TrajectoryCommands(node, np.asarray(arm['velocity'], dtype=float),
                                  np.asarray(arm['acceleration'], dtype=float),
                                  float(motion['trajectory_period']))
    raise ValueError(f'motion.joint_commands {kind!r}: one of {", ".join(KINDS)}')
