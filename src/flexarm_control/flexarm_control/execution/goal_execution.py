"""Executing a planned ``/move_to_pose`` goal: move, measure, correct (pure core of the
compensator node; the plan itself is :mod:`flexarm_control.execution.planning`).

* Every mode moves to the plan and then measures the tip, when the camera sees the plate.
* RIGID and PREDICTIVE end after that one move. They check the measured error only when the
  goal gave a tolerance (``checked``): beyond it the goal ends ``tolerance_not_met``, without a
  measurement ``measurement_failed``; unchecked, a missing measurement is only noted.
* After the one move, the measured error is held against the bound the plan stated
  (``stated``, widened by the camera's 95 % error ``camera``): beyond it, the goal's reason
  carries the warning with both figures (:func:`~.bound_check.beyond_bound`); the status is the
  tolerance's to decide, and without one the goal succeeds.
* AUTO that ran PREDICTIVE (``correct_on_miss``) and measures its tolerance missed goes on
  as CLOSED_LOOP from that measurement: its bound said PREDICTIVE would do, the camera says it
  did not (the arm changed since the model learned it), and correcting is what AUTO is for.
* CLOSED_LOOP corrects the commanded pose by the measured error
  (:meth:`~flexarm_control.execution.compensator.Compensator.correct`) until the measured error is
  within the tolerance, with at most ``max_corrections`` corrective moves after the first. Each
  move lands with the servos' own error, drawn anew, so a tolerance near their repeatability may be
  met at one move and missed at the next: a goal out of corrections ends at its best measured
  pose, not its last. The best is the smallest measured position error, the angle error
  breaking ties: an operator reads a miss in mm, and ranking by both would need a weighting of
  mm against deg that no goal states. If the last move is not the best, the best plan is
  commanded once more and measured; that measurement is the goal's final one (it may still
  meet the tolerance), and the reason gives it and the best seen.

The outcome is an :class:`Execution` whose ``status`` the node maps to the action's error
codes; nothing here knows ROS. Cancel and a failed move end the goal with the arm held.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from flexarm_control.execution.bound_check import beyond_bound
from flexarm_control.execution.compensator import Compensator, Plan
from flexarm_control.execution.modes import Mode
from flexarm_core.kinematics import UnreachableError, pose_error
from flexarm_motion.arm_motion import Abort, ArmMotion, Canceled, MoveFailed, never

# Execution.status values (the node maps them to MoveToPose result codes).
SUCCEEDED = 'succeeded'
CANCELED = 'canceled'
CONTROLLER_TIMEOUT = 'controller_timeout'
MEASUREMENT_FAILED = 'measurement_failed'
TOLERANCE_NOT_MET = 'tolerance_not_met'
UNREACHABLE = 'unreachable'

# Phases reported while a goal runs (the action feedback's PHASE_* values).
MOVING, SETTLING, MEASURING = 'moving', 'settling', 'measuring'


@dataclass(frozen=True)
class GoalSpec:
    """What a goal asks, with the server's defaults filled in."""

    target: np.ndarray         # (3,) [m, m, rad]
    mode: Mode
    position_tolerance: float  # [m] CLOSED_LOOP: always; RIGID/PREDICTIVE: 0 = not checked
    angle_tolerance: float     # [rad] as position_tolerance
    max_corrections: int       # CLOSED_LOOP corrective moves after the first
    stated: tuple[float, float] = (math.nan, math.nan)   # [m, rad] the plan's 95 % bound
    camera: tuple[float, float] = (0.0, 0.0)   # [m, rad] 95 % of a measurement's own error
    correct_on_miss: bool = False  # AUTO: a PREDICTIVE run that misses the tolerance corrects

    @property
    def max_moves(self) -> int:
        """The most moves the goal makes: CLOSED_LOOP's first, its corrections and the return
        to its best plan; one otherwise."""
        closing = self.mode == Mode.CLOSED_LOOP or self.correct_on_miss
        return self.max_corrections + 2 if closing else 1

    @property
    def checked(self) -> bool:
        """Whether the measured error must be within the tolerances."""
        return (self.mode == Mode.CLOSED_LOOP or self.position_tolerance > 0
                or self.angle_tolerance > 0)


@dataclass(frozen=True)
class Execution:
    status: str                    # one of the status constants above
    reason: str                    # why it did not succeed, or a note ('' if none)
    plan: Plan                     # the last plan commanded
    moves: int                     # moves made (0: nothing moved)
    measured: np.ndarray | None    # (3,) the last measured tip pose
    held_at: np.ndarray | None = None   # (4,) joints where a canceled goal held the arm
    first: np.ndarray | None = None     # (3,) the tip measured after the first move

    def errors(self, target: np.ndarray) -> tuple[float, float]:
        """(position [m], angle [rad]) error of the last measurement; (0, 0) without one."""
        return (0.0, 0.0) if self.measured is None else pose_error(target, self.measured)


# progress(phase, move number, plan, measured pose or None)
Progress = Callable[[str, int, Plan, np.ndarray | None], None]
# observe(joints the arm reported, measured tip pose): every measurement (the model health)
Observe = Callable[[np.ndarray, np.ndarray], None]


def _quiet(phase: str, move: int, plan: Plan, measured: np.ndarray | None) -> None:
    return None


def _unobserved(joints: np.ndarray, measured: np.ndarray) -> None:
    return None


def execute(spec: GoalSpec, plan: Plan, motion: ArmMotion, compensator: Compensator,
            abort: Abort = never, progress: Progress = _quiet,
            observe: Observe = _unobserved) -> Execution:
    """Run ``plan`` for the goal ``spec`` (module docstring) on ``motion``'s arm;
    ``observe(joints, measured)`` gets every measurement with the joints the arm reported."""
    measured = first = None
    move = 0
    best: tuple[float, float, int, Plan] | None = None   # CLOSED_LOOP: position, angle, move
    returned = False                                     # the best plan commanded again
    closing = spec.mode == Mode.CLOSED_LOOP              # measuring and correcting

    def ended(status: str, reason: str, held_at: np.ndarray | None = None) -> Execution:
        return Execution(status, reason, plan, move, measured, held_at, first)

    while True:
        move += 1
        progress(MOVING, move, plan, None)
        try:
            motion.move_to(plan.joints, abort)
            progress(SETTLING, move, plan, None)
            measurement = motion.measure(abort)
        except Canceled as exc:
            # Where the hold stopped the arm: the joints read a moment later may still be
            # on the way there (a braking arm overshoots its hold and comes back).
            held = exc.held_at if exc.held_at is not None else motion.arm.positions()
            return ended(CANCELED, str(exc), held)
        except MoveFailed as exc:
            return ended(CONTROLLER_TIMEOUT, str(exc))
        if measurement is None:
            why = motion.arm.measurement_problem
            if spec.checked:
                return ended(MEASUREMENT_FAILED, (
                    f'no valid settled tip pose within {motion.settings.measurement_timeout:.0f}'
                    ' s after the move' + ('' if spec.mode == Mode.CLOSED_LOOP
                                           else ' to check the tolerance')
                    + (f': {why}' if why else '')))
            return ended(SUCCEEDED, 'moved; no valid settled tip measurement'
                         + (f' ({why})' if why else ''))
        measured = measurement.pose
        first = measured if first is None else first
        observe(motion.arm.positions(), measured)
        progress(MEASURING, move, plan, measured)
        position, angle = pose_error(spec.target, measured)
        if not closing:
            warning = beyond_bound((position, angle), spec.stated, np.asarray(spec.camera))
            missed = _beyond_tolerance(spec, position, angle)
            if not missed:
                return ended(SUCCEEDED, warning)
            if not spec.correct_on_miss:
                return ended(TOLERANCE_NOT_MET, '; '.join(filter(None, [
                    'measured error beyond the tolerance: ' + missed, warning])))
            closing = True          # AUTO: measured beyond its tolerance, it corrects
        within = position <= spec.position_tolerance and angle <= spec.angle_tolerance
        if returned:
            final = (f'{_error_text(position, angle)} after {spec.max_corrections} corrections '
                     f'and a return to the best seen, {_error_text(*best[:2])} at move {best[2]}')
            if within:
                return ended(SUCCEEDED, 'within tolerance: ' + final)
            return ended(TOLERANCE_NOT_MET, final)
        if within:
            return ended(SUCCEEDED, '')
        if best is None or (position, angle) < best[:2]:
            best = (position, angle, move, plan)
        if move > spec.max_corrections:
            if best[3] is plan:
                return ended(TOLERANCE_NOT_MET, f'{_error_text(position, angle)} after '
                             f'{spec.max_corrections} corrections, the best seen')
            plan, returned = best[3], True
            continue
        try:
            plan = compensator.correct(plan, spec.target, measured)
        except UnreachableError as exc:
            return ended(UNREACHABLE, f'correction: {exc}')


def _error_text(position: float, angle: float) -> str:
    return f'{position * 1e3:.3f} mm / {math.degrees(angle):.4f} deg'


def _beyond_tolerance(spec: GoalSpec, position: float, angle: float) -> str:
    """Which of a RIGID/PREDICTIVE goal's tolerances the measured error misses ('' none)."""
    missed = []
    if spec.position_tolerance and position > spec.position_tolerance:
        missed.append(f'position {position * 1e3:.3f} mm > '
                      f'{spec.position_tolerance * 1e3:.3f} mm')
    if spec.angle_tolerance and angle > spec.angle_tolerance:
        missed.append(f'angle {math.degrees(angle):.4f} deg > '
                      f'{math.degrees(spec.angle_tolerance):.4f} deg')
    return ', '.join(missed)
