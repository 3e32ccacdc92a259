"""The arm as the control nodes see it: joint commands out, joint states and tip poses in.

Shared by the compensator and the learner, whose policies drive it as an
:class:`~flexarm_motion.arm_motion.Arm`. Commands follow one of ros2_controllers'
contracts (:mod:`flexarm_motion.ros.joint_commands`): a position set-point on
``/forward_position_controller/commands``, a trajectory on
``/joint_trajectory_controller/joint_trajectory`` or a FollowJointTrajectory goal of that
controller, so a real controller drops in. A move ends early when the controller says it failed
(rejected or aborted the goal): :attr:`ArmInterface.move_problem` gives its reason. A move or a
measurement waits in the arm's own time, the stamps of its joint states (sim time from the
simulator; a real arm's wall time): with several arms on one ``/clock`` a busy
simulator following it can lag by seconds, and its arm is not late for that. Waits are also
capped in wall time, so a stopped clock can never hang a goal. A wait also ends when
``/joint_states`` stop (the controller died or its link is down: nothing the arm does can be
seen any more), a move's as soon as its controller restarted (its command died with it), and
when the node shuts down (SIGINT/SIGTERM: the process can then exit).

Commands are sent only under a claim of the arm that holds (:class:`~flexarm_control.ros.
arm_claim.ArmClaim`, one motion at a time per arm): a command without one is a programming error
(:class:`NotHeld`), and a hold is sent only under a claim, or after it ended while no other
motion holds the arm.

Inputs are subscribed only while they are used: ``/joint_states`` while a goal drives the arm
(:meth:`ArmInterface.attached`), ``/tip_pose`` while a measurement waits for it; nobody asking
for tip poses lets the vision node and the camera rest (:mod:`flexarm_core.demand`). And
they are taken, not called back: the waiting thread takes what arrived each time it looks
(every ``_POLL`` s), so no message wakes the node's executor (at a 10x real-time factor
``/joint_states`` alone is 1000 messages a wall second, and a wake-up costs more than the
message). Of the joint states only the newest counts: a queue of one.
"""
from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription
from rclpy.time import Time
from sensor_msgs.msg import JointState

from flexarm_core import liveness, topics
from flexarm_core.goal_sender import full_name
from flexarm_core.kinematics import JOINT_NAMES
from flexarm_core.measurement import Measurement, average_frames
from flexarm_core.ros.taken import Taken, take
from flexarm_motion.controller_restart import restarted
from flexarm_motion.ros.arm_claim import ArmClaim
from flexarm_motion.ros.joint_commands import ForwardCommands, JointCommands
from flexarm_msgs.msg import TipPose

# A wait of T s of sim time may take at most this many times T (+ slack) of wall time.
_WALL_FACTOR = 3.0
_WALL_SLACK = 10.0
_POLL = 0.02   # [s] waits take the inputs that arrived this often
# [s, wall] without /joint_states, once they came, after which the controller counts as gone
# (times the liveness factor, :mod:`flexarm_core.liveness`). At 100 Hz of sim time even a
# simulator at a tenth of real time publishes every 0.1 s, but a starved simulator or
# subscriber has paused for over 1 s on a busy 2-core machine, so 3 s: still "within a few
# seconds" for a dead controller. The bridge's own link-loss timeout (heartbeats,
# PROTOCOL.md) is separate and stays at 1 s.
JOINT_SILENCE = 3.0
NEWEST = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)   # /joint_states
TIP_POSES = 10   # queue of /tip_pose: a measurement's frames, between two looks at most a few
# [s, wall] a measurement waits for a known camera's first frame before its sim-time timeout
# counts (times the liveness factor): the camera renders only for a subscriber, and it learns
# of a new one through discovery, a wall-clock matter: at x10 the 30 s of sim time are 3 s of
# wall time, less than a starved vision node has taken to start on a busy 2-core machine.
FIRST_FRAME = 2.0
RESTART_LOOK = 0.25   # [s, wall] between two looks of a move for its controller's restart


@dataclass(frozen=True)
class JointSnapshot:
    stamp: Time
    positions: np.ndarray   # (4,) in JOINT_NAMES order [rad, m, rad, rad]


def joint_positions(msg: JointState) -> np.ndarray | None:
    """The positions (4,) of ``JOINT_NAMES`` in a joint state, None if one is missing."""
    try:
        return np.array([msg.position[msg.name.index(n)] for n in JOINT_NAMES])
    except (ValueError, IndexError):
        return None


WHAT_TO_DO = ("see the vision node's diagnostics (flexarm status); a camera off its camera_info: "
              'flexarm calibrate --camera')


def measurement_problem(frames: list[TipPose], wanted: int) -> str:
    """Why ``frames`` (the tip poses heard while measuring) gave no measurement of ``wanted``
    valid settled frames: the vision node's own reason where it gave one."""
    if not frames:
        return ('no tip pose came from the vision node on /tip_pose: is it running, and does '
                'the camera publish images?')
    invalid = [f for f in frames if not f.valid]
    if len(invalid) == len(frames):
        return (f'the vision node found no valid pose in {len(frames)} frame(s): '
                f'{invalid[-1].status or "no reason given"} ({WHAT_TO_DO})')
    settled = [f for f in frames if f.valid and f.settled]
    if not settled:
        unsettled = [f for f in frames if f.valid]
        return f'the tip did not settle: {unsettled[-1].status or "still moving"}'
    last = invalid[-1].status if invalid else ''
    return (f'only {len(settled)} of the {wanted} valid settled frames needed'
            + (f' (the others: {last})' if last else ''))


class RestartWatch:
    """The controller a move's command went to (the publishers of ``/joint_states`` as it is
    sent), looked at again every :data:`RESTART_LOOK` s: a move ends as soon as its node
    restarted (:mod:`flexarm_motion.controller_restart`)."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._topic = node.resolve_topic_name(topics.JOINT_STATES)
        self._at_command = self._publishers()
        self._next = time.monotonic() + RESTART_LOOK
        self.problem = ''

    def look(self) -> str:
        """The restart's problem ('' while the controller is the one commanded)."""
        now = time.monotonic()
        if not self.problem and now >= self._next:
            self._next = now + RESTART_LOOK
            names = restarted(self._at_command, self._publishers())
            if names:
                self.problem = (f'the controller {names[0]} restarted during the move: the '
                                'command went to the one before it and died with it')
        return self.problem

    def _publishers(self) -> list[tuple[bytes, str]]:
        return [(bytes(i.endpoint_gid), full_name(i.node_namespace, i.node_name))
                for i in self._node.get_publishers_info_by_topic(self._topic)]


class NotHeld(RuntimeError):
    """A command without a claim of the arm that holds: every motion claims the arm first."""


class ArmInterface:
    """Joint commands, joint states and tip poses of one node, with bounded waits."""

    def __init__(self, node: Node, frames_kept: int = 50,
                 commands: JointCommands | None = None, claim: ArmClaim | None = None) -> None:
        self._node = node
        self.claim = claim or ArmClaim(node)
        self._lock = threading.Lock()
        self._taken = Taken()
        self._joint_input: Subscription | None = None     # while attached
        self._tip_input: Subscription | None = None       # while measuring
        self._joints: JointSnapshot | None = None
        self._joints_heard: float | None = None   # [s, monotonic] when the newest was taken
        self._frames: deque[TipPose] = deque(maxlen=frames_kept)
        self.measurement_problem = ''     # why the last measure() failed ('' if it did not)
        self.move_problem = ''     # the controller's reason the last move() failed ('' none)
        self._commands = commands or ForwardCommands(node)

    @contextmanager
    def attached(self) -> Iterator[None]:
        """Subscribe ``/joint_states`` for the duration (a goal), starting from none: what an
        earlier goal saw is not the arm now. Raw: only the newest is parsed, when taken."""
        with self._lock:
            self._joints = self._joints_heard = None
        self._joint_input = self._subscribe(JointState, topics.JOINT_STATES, NEWEST, raw=True)
        try:
            yield
        finally:
            self._node.destroy_subscription(self._joint_input)
            self._joint_input = None

    # --- inputs -----------------------------------------------------------------------------
    def _subscribe(self, msg_type: type, topic: str, qos: QoSProfile | int,
                   raw: bool = False) -> Subscription:
        return self._node.create_subscription(msg_type, topic, lambda _: None,   # never run
                                              qos, callback_group=self._taken, raw=raw)

    def _take_inputs(self) -> None:
        """Take the newest joint state and every tip pose that arrived (lock held)."""
        raw = None if self._joint_input is None else take(self._joint_input)
        if raw is not None:
            self._joints_heard = time.monotonic()
            msg = deserialize_message(raw, JointState)
            positions = joint_positions(msg)
            if positions is not None:       # else a joint is missing: keep the last state
                self._joints = JointSnapshot(Time.from_msg(msg.header.stamp), positions)
        while self._tip_input is not None and (frame := take(self._tip_input)) is not None:
            self._frames.append(frame)

    @property
    def joints(self) -> JointSnapshot | None:
        with self._lock:
            self._take_inputs()
            return self._joints

    def positions(self) -> np.ndarray | None:
        """The newest joint positions (4,), None before the first joint state."""
        snapshot = self.joints
        return None if snapshot is None else snapshot.positions

    def now(self) -> Time:
        return self._node.get_clock().now()

    def arm_time(self) -> Time:
        """The arm's time: the stamp of the newest joint state taken (the node's before one)."""
        joints = self._joints
        return self.now() if joints is None else joints.stamp

    @property
    def controller_silent(self) -> bool:
        """Whether ``/joint_states`` came once but not for ``JOINT_SILENCE`` s (wall, scaled)."""
        heard = self._joints_heard
        return heard is not None and time.monotonic() - heard > liveness.limit(JOINT_SILENCE)

    # --- commands ---------------------------------------------------------------------------
    def command(self, q: np.ndarray) -> None:
        """Send the arm to ``q`` from where it is now (:class:`NotHeld` without a claim)."""
        if not self.claim.holds():
            raise NotHeld(self.claim.lost or 'the arm is commanded only under a claim '
                          '(ArmClaim.claimed)')
        if self._node.context.ok():       # a node that shuts down sends nothing any more
            self._commands.send(self.positions(), np.asarray(q, dtype=float))

    def hold(self) -> np.ndarray | None:
        """Stop the arm where it is (the joints now): under a claim, or after it ended while
        no other motion holds the arm."""
        snapshot = self.joints
        if snapshot is not None:
            if self._node.context.ok() and self.claim.may_stop():
                self._commands.stop(snapshot.positions)
            return snapshot.positions
        return None

    # --- waits ------------------------------------------------------------------------------
    def wait_until(self, predicate: Callable[[], bool], timeout: float,
                   abort: Callable[[], bool] = lambda: False,
                   clock: Callable[[], Time] | None = None,
                   counting: Callable[[], bool] = lambda: True) -> bool:
        """Wait until ``predicate()`` (evaluated under the lock, on the inputs just taken) or
        ``timeout`` s of ``clock`` (default: the node's), counted from when ``counting()``
        (under the lock) first holds.

        Returns False on timeout, when ``abort()`` becomes true (e.g. a cancel request), when
        ``/joint_states`` stopped (:attr:`controller_silent`) or when the node shuts down.
        Under ``use_sim_time`` the node time is 0 until the first ``/clock`` arrives and then
        jumps to the simulator's time: the wait starts counting at the first non-zero time.
        """
        clock = clock or self.now
        start: Time | None = None
        wall_deadline = float('inf')
        while True:
            with self._lock:
                self._take_inputs()
                if predicate():
                    return True
                began = start is None and counting()
            if began:
                start = clock()
                wall_deadline = time.monotonic() + _WALL_FACTOR * timeout + _WALL_SLACK
            if (abort() or time.monotonic() > wall_deadline or self.controller_silent
                    or not self._node.context.ok()):
                return False
            if start is not None:
                now = clock()
                if start.nanoseconds == 0:
                    start = now
                elif (now - start).nanoseconds * 1e-9 > timeout:
                    return False
            time.sleep(_POLL)

    def wait_for_joints(self, timeout: float) -> bool:
        """Whether a joint state arrives within ``timeout`` wall seconds of an ordinary machine,
        liveness-scaled (the controller's liveness is a wall-clock matter: at a 10x real-time
        factor 5 s of sim time would be half a second, less than DDS matching may take on a
        loaded machine, and a simulator taking the /clock over waits a scaled silence first)."""
        deadline = time.monotonic() + liveness.limit(timeout)
        while self.joints is None:
            if time.monotonic() > deadline or not self._node.context.ok():
                return False
            time.sleep(_POLL)
        return True

    def move(self, q: np.ndarray, tolerance: np.ndarray, timeout: float,
             abort: Callable[[], bool] = lambda: False) -> bool:
        """Command ``q`` and wait until every joint is within ``tolerance`` of it; False also
        when the controller ends the move short of it, with its reason in
        :attr:`move_problem` (kept there: the hold that follows is a command of its own)."""
        target = np.asarray(q, dtype=float)
        self.move_problem = ''
        restart = RestartWatch(self._node)
        self.command(target)

        def arrived() -> bool:
            joints = self._joints
            return joints is not None and bool(np.all(np.abs(joints.positions - target)
                                                      <= tolerance))

        def ended() -> bool:
            return abort() or bool(self._commands.problem) or bool(restart.look())
        if self.wait_until(arrived, timeout, ended, self.arm_time):
            return True
        self.move_problem = self._commands.problem or restart.problem
        return False

    def measure(self, frames: int, timeout: float, abort: Callable[[], bool] = lambda: False,
                ) -> Measurement | None:
        """Average ``frames`` valid, settled tip poses captured after now in the arm's time (the
        node's clock can be a few /clock periods behind it, or ahead); None on timeout, which
        counts from the first frame (or :data:`FIRST_FRAME` wall seconds without one, or at once
        when the graph knows no camera).
        ``/tip_pose`` is subscribed for the measurement only."""
        with self._lock:
            self._take_inputs()
            since = self.arm_time()
            self._frames.clear()

        def usable() -> list[TipPose]:
            return [f for f in self._frames
                    if f.valid and f.settled and Time.from_msg(f.header.stamp) >= since]

        self._tip_input = self._subscribe(TipPose, topics.TIP_POSE, TIP_POSES)
        first_frame = time.monotonic() + liveness.limit(FIRST_FRAME)

        def counting() -> bool:
            """Once a frame came, or no camera is known to the graph, or it never sent one."""
            return (bool(self._frames) or time.monotonic() > first_frame
                    or not self._node.count_publishers(topics.TIP_POSE))

        try:
            if not self.wait_until(lambda: len(usable()) >= frames, timeout, abort,
                                   self.arm_time, counting=counting):
                with self._lock:
                    self.measurement_problem = measurement_problem(
                        [f for f in self._frames if Time.from_msg(f.header.stamp) >= since],
                        frames)
                return None
            with self._lock:
                chosen = usable()[:frames]
                self.measurement_problem = ''
        finally:
            self._node.destroy_subscription(self._tip_input)
            self._tip_input = None
        return average_frames(
            np.array([[f.pose.x, f.pose.y, f.pose.phi] for f in chosen]),
            holes_used=min(f.holes_used for f in chosen),
            residual=max(f.residual for f in chosen))
