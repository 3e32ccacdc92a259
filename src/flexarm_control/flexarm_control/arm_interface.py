"""The arm as the control nodes see it: joint commands out, joint states and tip poses in.

Shared by the compensator and the learner, whose policies drive it as an
:class:`~flexarm_control.arm_motion.Arm`. Commands go to ros2_control's
``/forward_position_controller/commands`` (one value per joint, in ``JOINT_NAMES`` order), so a
real controller drops in. Waits are in the node's clock (sim time under ``use_sim_time``) and
are also capped in wall time, so a stopped ``/clock`` can never hang a goal. A wait also ends
when ``/joint_states`` stop (the controller died or its link is down: nothing the arm does can
be seen any more) and when the node shuts down (SIGINT/SIGTERM: the process can then exit).
"""
from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from rclpy.callback_groups import CallbackGroup
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rclpy.serialization import deserialize_message
from rclpy.time import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from flexarm_control import liveness, topics
from flexarm_control.kinematics import JOINT_NAMES
from flexarm_control.measurement import Measurement, average_frames
from flexarm_msgs.msg import TipPose

# A wait of T s of sim time may take at most this many times T (+ slack) of wall time.
_WALL_FACTOR = 3.0
_WALL_SLACK = 10.0
_POLL = 0.02   # [s] waits re-check joint states this often (tip poses wake them at once)
# [s, wall] without /joint_states, once they came, after which the controller counts as gone
# (times the liveness factor, :mod:`flexarm_control.liveness`). At 100 Hz of sim time even a
# simulator at a tenth of real time publishes every 0.1 s, but a starved simulator or
# subscriber has paused for over 1 s on a busy 2-core machine, so 3 s: still "within a few
# seconds" for a dead controller. The bridge's own link-loss timeout (heartbeats,
# PROTOCOL.md) is separate and stays at 1 s.
JOINT_SILENCE = 3.0


@dataclass(frozen=True)
class JointSnapshot:
    stamp: Time
    positions: np.ndarray   # (4,) in JOINT_NAMES order [rad, m, rad, rad]


class ArmInterface:
    """Joint commands, joint states and tip poses of one node, with bounded waits."""

    def __init__(self, node: Node, callback_group: CallbackGroup | None = None,
                 frames_kept: int = 50) -> None:
        self._node = node
        self._cond = threading.Condition()
        self._joints: JointSnapshot | None = None
        self._joints_raw: bytes | None = None     # newest /joint_states, not yet parsed
        self._joints_heard: float | None = None   # [s, monotonic] when the newest came
        self._frames: deque[TipPose] = deque(maxlen=frames_kept)
        self._publisher = node.create_publisher(Float64MultiArray, topics.JOINT_COMMANDS, 10)
        # Raw: at a 10x real-time factor /joint_states arrives 1000 times a wall second; only
        # the newest is parsed, when a wait looks at it.
        node.create_subscription(JointState, topics.JOINT_STATES, self._on_joint_state,
                                 qos_profile_sensor_data, callback_group=callback_group,
                                 raw=True)
        node.create_subscription(TipPose, topics.TIP_POSE, self._on_tip_pose, 10,
                                 callback_group=callback_group)

    # --- inputs -----------------------------------------------------------------------------
    def _on_joint_state(self, raw: bytes) -> None:
        with self._cond:
            self._joints_raw = raw
            self._joints_heard = time.monotonic()

    def _parse_joints(self) -> JointSnapshot | None:
        """The newest joint state (call with the lock held)."""
        if self._joints_raw is not None:
            msg = deserialize_message(self._joints_raw, JointState)
            self._joints_raw = None
            try:
                positions = np.array([msg.position[msg.name.index(n)] for n in JOINT_NAMES])
            except (ValueError, IndexError):
                return self._joints
            self._joints = JointSnapshot(Time.from_msg(msg.header.stamp), positions)
        return self._joints

    def _on_tip_pose(self, msg: TipPose) -> None:
        with self._cond:
            self._frames.append(msg)
            self._cond.notify_all()

    @property
    def joints(self) -> JointSnapshot | None:
        with self._cond:
            return self._parse_joints()

    def positions(self) -> np.ndarray | None:
        """The newest joint positions (4,), None before the first joint state."""
        snapshot = self.joints
        return None if snapshot is None else snapshot.positions

    def now(self) -> Time:
        return self._node.get_clock().now()

    @property
    def controller_silent(self) -> bool:
        """Whether ``/joint_states`` came once but not for ``JOINT_SILENCE`` s (wall, scaled)."""
        heard = self._joints_heard
        return heard is not None and time.monotonic() - heard > liveness.limit(JOINT_SILENCE)

    # --- commands ---------------------------------------------------------------------------
    def command(self, q: np.ndarray) -> None:
        if self._node.context.ok():       # a node that shuts down sends nothing any more
            self._publisher.publish(Float64MultiArray(data=[float(v) for v in q]))

    def hold(self) -> np.ndarray | None:
        """Stop the arm where it is: command the current joint positions."""
        snapshot = self.joints
        if snapshot is not None:
            self.command(snapshot.positions)
            return snapshot.positions
        return None

    # --- waits ------------------------------------------------------------------------------
    def wait_until(self, predicate: Callable[[], bool], timeout: float,
                   abort: Callable[[], bool] = lambda: False) -> bool:
        """Wait until ``predicate()`` (evaluated under the lock) or ``timeout`` s of node time.

        Returns False on timeout, when ``abort()`` becomes true (e.g. a cancel request), when
        ``/joint_states`` stopped (:attr:`controller_silent`) or when the node shuts down.
        Under ``use_sim_time`` the node time is 0 until the first ``/clock`` arrives and then
        jumps to the simulator's time: the wait starts counting at the first non-zero time.
        """
        start = self.now()
        wall_deadline = time.monotonic() + _WALL_FACTOR * timeout + _WALL_SLACK
        with self._cond:
            while not predicate():
                if (abort() or time.monotonic() > wall_deadline or self.controller_silent
                        or not self._node.context.ok()):
                    return False
                now = self.now()
                if start.nanoseconds == 0:
                    start = now
                elif (now - start).nanoseconds * 1e-9 > timeout:
                    return False
                self._cond.wait(_POLL)
        return True

    def wait_for_joints(self, timeout: float) -> bool:
        """Whether a joint state arrives within ``timeout`` wall seconds (the controller's
        liveness is a wall-clock matter: at a 10x real-time factor 5 s of sim time would be
        half a second, less than DDS matching may take on a loaded machine)."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._parse_joints() is None:
                if time.monotonic() > deadline or not self._node.context.ok():
                    return False
                self._cond.wait(_POLL)
        return True

    def move(self, q: np.ndarray, tolerance: np.ndarray, timeout: float,
             abort: Callable[[], bool] = lambda: False) -> bool:
        """Command ``q`` and wait until every joint is within ``tolerance`` of it."""
        target = np.asarray(q, dtype=float)
        self.command(target)

        def arrived() -> bool:
            joints = self._parse_joints()
            return joints is not None and bool(np.all(np.abs(joints.positions - target)
                                                      <= tolerance))
        return self.wait_until(arrived, timeout, abort)

    def measure(self, frames: int, timeout: float, abort: Callable[[], bool] = lambda: False,
                ) -> Measurement | None:
        """Average ``frames`` valid, settled tip poses captured after now; None on timeout."""
        since = self.now()
        with self._cond:
            self._frames.clear()

        def usable() -> list[TipPose]:
            return [f for f in self._frames
                    if f.valid and f.settled and Time.from_msg(f.header.stamp) >= since]

        if not self.wait_until(lambda: len(usable()) >= frames, timeout, abort):
            return None
        with self._cond:
            chosen = usable()[:frames]
        return average_frames(
            np.array([[f.pose.x, f.pose.y, f.pose.phi] for f in chosen]),
            holes_used=min(f.holes_used for f in chosen),
            residual=max(f.residual for f in chosen))
