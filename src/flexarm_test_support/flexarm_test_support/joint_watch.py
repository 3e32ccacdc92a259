"""What node tests see of the arm on ``/joint_states``: the latest joints, and for how long (in
the simulator's time, from the stamps) they have not moved. "The arm has stopped" is read
from the arm, never from a wall-clock sleep that a slowed-down simulator can outlast."""
from __future__ import annotations

import numpy as np
from sensor_msgs.msg import JointState

MOVED = 1e-7   # [rad, m] a joint that changes by more than this moved


class JointWatch:
    """Subscribe :meth:`on_joints` to ``/joint_states``."""

    def __init__(self) -> None:
        self.q: np.ndarray | None = None
        self.still_for = 0.0      # [s, sim time] since the joints last moved
        self._still_since = 0.0

    def on_joints(self, msg: JointState) -> None:
        q = np.array(msg.position)
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        if self.q is None or np.max(np.abs(q - self.q)) > MOVED:
            self._still_since = stamp
        self.q = q
        self.still_for = stamp - self._still_since
