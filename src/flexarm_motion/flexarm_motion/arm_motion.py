"""Moving the arm and measuring its tip, as the control policies do it (pure core).

:class:`ArmMotion` owns the settings every move and measurement share, in one place for the
compensator and the learner (config/motion.yaml, ``motion.*``): when the joints count as
arrived, how long a move may take (the slowest joint's travel time at the Table 1 speeds plus
``move_timeout_margin``) and how a measurement is taken (``measurement_frames`` valid, settled
tip poses averaged within ``measurement_timeout``) and from which side a pose is approached.

Approach: friction makes a real arm's deflection depend on the direction from which a pose is
reached (hysteresis, a band inside each joint's backlash). Every move therefore ends with a
final leg of ``approach`` (4,) joint travel in its sign's direction: the arm first goes to
``joints - approach`` (clipped to the joint limits), then to ``joints``, so the learner's
samples and the compensator's goals meet each pose from the same side and the hysteresis is a
repeatable part of the deflection the model learns. ``approach`` must exceed the travel that
takes up the friction band (2 x 30 % of the backlash: 0.84 mrad at joint 4; some 10 um of
joint 2); all zero turns it off. It drives any :class:`Arm` — the nodes'
:class:`~flexarm_motion.ros.arm_interface.ArmInterface` or a fake in unit tests — and turns what
goes wrong into exceptions the policies handle: :class:`Canceled` (the arm is held where it
is) and :class:`MoveFailed` (the joints did not arrive in time, the controller ended the move
short of them and said why, or it fell silent: the arm is held and its state is unknown).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from flexarm_core.kinematics import JOINT_NAMES, JOINT_UNITS, ArmGeometry
from flexarm_core.measurement import Measurement

Abort = Callable[[], bool]


def never() -> bool:
    return False


class Arm(Protocol):
    """What the policies need of an arm: joint positions, a move, a measurement, a hold."""

    @property
    def controller_silent(self) -> bool:
        """Whether the controller stopped reporting its joints."""

    def positions(self) -> np.ndarray | None:
        """The joints now (4,) [rad, m, rad, rad], None before the first report."""

    def move(self, q: np.ndarray, tolerance: np.ndarray, timeout: float,
             abort: Abort = never) -> bool:
        """Command ``q``; whether every joint came within ``tolerance`` of it in time (False
        also when the controller ended the move, with its reason in :attr:`move_problem`)."""

    @property
    def move_problem(self) -> str:
        """Why the controller ended the last move short of its target, in its words ('' if it
        did not say)."""

    def measure(self, frames: int, timeout: float, abort: Abort = never,
                ) -> Measurement | None:
        """``frames`` valid settled tip poses taken after now, averaged; None on timeout,
        with the reason in :attr:`measurement_problem`."""

    @property
    def measurement_problem(self) -> str:
        """Why the last measurement failed, in the sensor's words ('' if it did not)."""

    def hold(self) -> np.ndarray | None:
        """Stop where the arm is; the joints it holds."""


class Canceled(Exception):
    """The caller aborted a move or measurement; the arm is held at ``held_at`` (the joints
    commanded to stop it, where it comes to rest), None if it was not moving."""

    def __init__(self, reason: str, held_at: np.ndarray | None = None) -> None:
        super().__init__(reason)
        self.held_at = held_at


class MoveFailed(Exception):
    """The joints did not reach the command; the arm is held."""

    def __init__(self, reason: str, controller_lost: bool) -> None:
        super().__init__(reason)
        self.controller_lost = controller_lost


@dataclass(frozen=True)
class MotionSettings:
    arrival_tolerance: np.ndarray   # (4,) [rad, m, rad, rad] joints within this have arrived
    move_timeout_margin: float      # [s] added to the slowest joint's travel time
    measurement_frames: int         # valid settled tip poses averaged per measurement
    measurement_timeout: float      # [s] for them, after the joints arrived
    approach: np.ndarray            # (4,) [rad, m, rad, rad] final leg of every move (0: none)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> MotionSettings:
        """From config/motion.yaml ``motion.*``; ValueError for a value out of range."""
        settings = cls(np.asarray(d['arrival_tolerance'], dtype=float),
                       float(d['move_timeout_margin']), int(d['measurement_frames']),
                       float(d['measurement_timeout']),
                       np.asarray(d['approach'], dtype=float))
        if (settings.arrival_tolerance.shape != (4,) or np.any(settings.arrival_tolerance <= 0)
                or settings.move_timeout_margin < 0 or settings.measurement_frames < 1
                or settings.measurement_timeout <= 0 or settings.approach.shape != (4,)):
            raise ValueError('motion: arrival_tolerance 4 values > 0, move_timeout_margin >= 0, '
                             'measurement_frames >= 1, measurement_timeout > 0, approach 4 values')
        return settings


class ArmMotion:
    """Moves an :class:`Arm` and measures its tip under one set of :class:`MotionSettings`."""

    def __init__(self, arm: Arm, geometry: ArmGeometry, settings: MotionSettings) -> None:
        self.arm = arm
        self.geometry = geometry        # joint speeds (Table 1) and limits
        self.settings = settings

    def timeout(self, joints: np.ndarray) -> float:
        """[s] a move from where the arm is to ``joints`` may take."""
        now = self.arm.positions()
        travel = (0.0 if now is None
                  else float(np.max(np.abs(joints - now) / self.geometry.velocity)))
        return travel + self.settings.move_timeout_margin

    def approach_pose(self, joints: np.ndarray) -> np.ndarray | None:
        """Where a move to ``joints`` starts its final leg, None without an approach."""
        if not np.any(self.settings.approach):
            return None
        g = self.geometry
        return np.clip(joints - self.settings.approach, g.lower, g.upper)

    def move_to(self, joints: np.ndarray, abort: Abort = never) -> None:
        """Move to ``joints`` by way of its approach pose and wait until they arrived;
        :class:`Canceled` when ``abort()`` became true, :class:`MoveFailed` when they did
        not arrive in time (both hold the arm)."""
        joints = np.asarray(joints, dtype=float)
        before = self.approach_pose(joints)
        if before is not None:
            self._leg(before, abort)
        self._leg(joints, abort)

    def _leg(self, joints: np.ndarray, abort: Abort) -> None:
        timeout = self.timeout(joints)
        start = self.arm.positions()
        arrived = self.arm.move(joints, self.settings.arrival_tolerance, timeout, abort)
        if abort():
            raise Canceled('canceled; arm held', self.arm.hold())
        if not arrived:
            lost = self.arm.controller_silent
            ended = self.arm.move_problem
            short = self.short_of(joints, start, self.arm.positions())
            self.arm.hold()
            raise MoveFailed(
                'the controller stopped publishing /joint_states mid-move (died, or its link '
                "was lost): the arm's state is unknown" if lost else
                ended or f'joints did not reach the command within {timeout:.0f} s{short}', lost)

    def short_of(self, joints: np.ndarray, start: np.ndarray | None,
                 now: np.ndarray | None) -> str:
        """How a move from ``start`` that ended at ``now`` fell short of ``joints``: the joint
        farthest off (in arrival tolerances) and whether the arm moved at all, which tells an
        arm that was slow from a command the controller never got ('' unknown)."""
        if now is None:
            return ''
        tolerance = self.settings.arrival_tolerance
        off = np.abs(joints - now)
        worst = int(np.argmax(off / tolerance))
        text = f': {JOINT_NAMES[worst]} {off[worst]:.3g} {JOINT_UNITS[worst]} from it'
        if start is not None and np.all(np.abs(now - start) <= tolerance):
            text += ', and the arm did not move (did the controller get the command?)'
        return text

    def measure(self, abort: Abort = never) -> Measurement | None:
        """The tip where the arm stands, None if no valid settled measurement came in time;
        :class:`Canceled` when ``abort()`` became true."""
        s = self.settings
        measurement = self.arm.measure(s.measurement_frames, s.measurement_timeout, abort)
        if abort():
            raise Canceled('canceled after the move')
        return measurement
