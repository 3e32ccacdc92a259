"""A ``trajectory_msgs/JointTrajectory`` as the arm's joints take it: what the simulator and a
joint trajectory controller stand-in read from joint_trajectory_controller's topic."""
from __future__ import annotations

import numpy as np
from trajectory_msgs.msg import JointTrajectory

from flexarm_core.joint_trajectory import SampledTrajectory
from flexarm_core.kinematics import JOINT_NAMES


def trajectory_from(msg: JointTrajectory) -> SampledTrajectory:
    """The points of ``msg`` in ``JOINT_NAMES`` order (velocities zero where a point has
    none); ValueError naming what is wrong."""
    names = list(msg.joint_names)
    if sorted(names) != sorted(JOINT_NAMES):
        raise ValueError(f'trajectory joints {names}: expected {list(JOINT_NAMES)}')
    order = [names.index(n) for n in JOINT_NAMES]
    if any(len(p.positions) != len(names) or len(p.velocities) not in (0, len(names))
           for p in msg.points):
        raise ValueError('trajectory point without a position (or velocity) per joint')
    return SampledTrajectory.from_points(
        np.zeros(len(order)),
        np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
                  for p in msg.points]),
        np.array([[p.positions[i] for i in order] for p in msg.points]),
        np.array([[p.velocities[i] if len(p.velocities) else 0.0 for i in order]
                  for p in msg.points]))
