"""What a move asks of joint_trajectory_controller as a ``control_msgs/FollowJointTrajectory``
goal, and how its answer reads: the messages of the ``follow_joint_trajectory`` contract
(:mod:`flexarm_motion.ros.joint_commands`), built and read without a node.

The goal carries the move's shaped trajectory and, per joint, the tolerances the controller
holds it to (a value the goal gives overrides the controller's own ``constraints``,
config/controllers.yaml, which keep the same values for clients that give none):

* path (config/arm.yaml ``arm.trajectory_tolerance.path``): how far a joint may be off the
  trajectory while it runs before the controller stops the move (PATH_TOLERANCE_VIOLATED);
* goal: config/motion.yaml ``motion.arrival_tolerance``, where flexarm counts the joints as
  arrived, so the controller's success and flexarm's arrival mean the same;
* goal time (``arm.trajectory_tolerance.goal_time``): how long after the trajectory's end the
  joints may take to come within the goal tolerance (else GOAL_TOLERANCE_VIOLATED).

Velocity and acceleration tolerances are left 0, the controller's own (its
``stopped_velocity_tolerance`` at the goal).

The answer: a rejected goal, or a result other than SUCCESSFUL, is the move's failure in the
controller's words (:func:`rejection`, :func:`failure`). A ROS 2 action's rejection carries no
reason (joint_trajectory_controller logs it), so a server that wants its client to know why
accepts the goal and aborts it with INVALID_GOAL and an ``error_string``.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration
from trajectory_msgs.msg import JointTrajectory

from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance

CONTROLLER = 'joint_trajectory_controller'
_CODES = ('SUCCESSFUL', 'INVALID_GOAL', 'INVALID_JOINTS', 'OLD_HEADER_TIMESTAMP',
          'PATH_TOLERANCE_VIOLATED', 'GOAL_TOLERANCE_VIOLATED')
CODE_NAMES = {getattr(FollowJointTrajectory.Result, name): name for name in _CODES}


@dataclass(frozen=True)
class TrajectoryTolerances:
    path: np.ndarray     # (4,) [rad, m, rad, rad] off the trajectory while it runs
    goal: np.ndarray     # (4,) [rad, m, rad, rad] off its end, to succeed
    goal_time: float     # [s] after the trajectory's end to come within ``goal``

    @classmethod
    def from_dicts(cls, arm: Mapping[str, Any], motion: Mapping[str, Any],
                   ) -> TrajectoryTolerances:
        """From config/arm.yaml ``arm.*`` and config/motion.yaml ``motion.*``; ValueError
        naming a value out of range."""
        given = arm['trajectory_tolerance']
        tolerances = cls(np.asarray(given['path'], dtype=float),
                         np.asarray(motion['arrival_tolerance'], dtype=float),
                         float(given['goal_time']))
        if tolerances.path.shape != (4,) or not np.all(tolerances.path > 0):
            raise ValueError('arm.trajectory_tolerance.path: 4 values > 0 [rad, m, rad, rad]')
        if tolerances.goal.shape != (4,) or not np.all(tolerances.goal > 0):
            raise ValueError('motion.arrival_tolerance: 4 values > 0 [rad, m, rad, rad]')
        if not tolerances.goal_time > 0:
            raise ValueError('arm.trajectory_tolerance.goal_time: > 0 s (0 would let the '
                             'controller wait for ever)')
        return tolerances


def _seconds(value: float) -> Duration:
    nanoseconds = round(value * 1e9)
    return Duration(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def goal_message(trajectory: JointTrajectory, tolerances: TrajectoryTolerances,
                 ) -> FollowJointTrajectory.Goal:
    """The goal of ``trajectory`` with ``tolerances`` for its joints (in its joints' order)."""
    names: Sequence[str] = trajectory.joint_names
    return FollowJointTrajectory.Goal(
        trajectory=trajectory,
        path_tolerance=[JointTolerance(name=n, position=float(p))
                        for n, p in zip(names, tolerances.path)],
        goal_tolerance=[JointTolerance(name=n, position=float(g))
                        for n, g in zip(names, tolerances.goal)],
        goal_time_tolerance=_seconds(tolerances.goal_time))


def rejection() -> str:
    """The failure of a goal the controller rejected."""
    return (f'{CONTROLLER} rejected the move (a rejection carries no reason: its log says '
            'why, e.g. a trajectory it does not take, or the controller is not active)')


def failure(status: int, error_code: int, error_string: str) -> str:
    """Why a goal that ended with ``status`` and its result's ``error_code`` and
    ``error_string`` did not move the arm where it was sent ('' if it did). flexarm never
    cancels its goals (a stop is a goal of its own), so a canceled one was canceled by
    another client of the controller."""
    reason = error_string.strip()
    successful = error_code == FollowJointTrajectory.Result.SUCCESSFUL
    if status == GoalStatus.STATUS_CANCELED:
        return f'{CONTROLLER} canceled the move (another client of the controller canceled it)'
    if status == GoalStatus.STATUS_SUCCEEDED and successful:
        return ''
    # no error code, yet the goal did not succeed: its status is all there is
    name = f'status {status}' if successful else CODE_NAMES.get(error_code,
                                                                 f'error code {error_code}')
    return f'{CONTROLLER} aborted the move: {name} ({reason or "no reason given"})'
