"""What a ``/move_to_pose`` goal may ask, and how long it may hold the arm (pure policy of the
compensator node).

Bounds: a goal beyond them is refused with INVALID_GOAL before anything moves.

* Every number finite and the mode known.
* The target angle ``phi`` within [-pi, pi] (-pi and pi are one orientation). An angle is
  never wrapped: ``phi = 1e9`` rad is a mistake, not the 33.08 deg it wraps to.
* A tolerance is 0 (CLOSED_LOOP: the server's default; RIGID/PREDICTIVE: not checked) or
  within [floor, ceiling]. The floors are what the camera can tell apart: the vision node
  calls a resting tip settled when consecutive poses agree within ``settle.stability``
  (0.02 mm) and ``settle.angle_stability`` (0.003 deg) of config/vision.yaml, some 4 x its
  noise; a measured error below them is noise, so a tolerance below them cannot be told met
  from missed, and a CLOSED_LOOP goal would only spend its corrections. The servos'
  repeatability sets no floor: the control side has no nominal figure for it. The paper
  states none (Table 1 gives ranges, speeds and drives; Tables 4-5 the joints' play and
  backlash, which every move's approach leg takes up the same way, config/motion.yaml, so they
  are no repeatability), a site knows it only from the servos' data sheet or a repeatability
  test, and the simulator's config/sim.yaml is not the control side's to read. A tolerance
  under it is accepted: a CLOSED_LOOP goal then meets it at some moves and misses it at
  others, and one out of corrections ends at its best measured pose and says so
  (:mod:`flexarm_control.execution.goal_execution`). The ceilings, 100 mm and 10 deg, are 4-5 x the
  largest error of the rigid model (24 mm, 2.1 deg, Table 10): a tolerance beyond them checks
  nothing and is most likely a unit slip (mm given as m).
* ``max_corrections`` at most :data:`MAX_CORRECTIONS` (10, twice the default 5). Each
  correction lands with the servos' own error, drawn anew at each move: with everything on,
  4 of 1 200 CLOSED_LOOP goals still missed 0.05 mm after 5 corrections (benchmarks/
  error_budget.py), a miss chance of about 0.4 per move, so more than 10 would matter to
  fewer than 1 goal in 30 000; a goal that keeps missing has a cause more moves do not mend
  (camera, model). Checked in every mode: the field is wrong whatever mode ignores it.

Time limit (:func:`time_limit`): a goal may hold the arm for at most ``TIME_MARGIN`` times the
sum of its moves' own timeouts, counted in the arm's time (sim time: the graph follows the
simulator's clock, so the limit holds at any real-time factor, and a wall limit would need to
know it). Per move (:func:`move_budget`): the slowest joint's travel over its whole range at
its Table 1 speed plus the approach leg, ``move_timeout_margin`` for each of the two legs and
``measurement_timeout`` (config/motion.yaml): 86 s. The per-move timeouts already end a move
that does not arrive or a measurement that does not come; the limit ends a goal that hangs
for a reason none of them catches (the margin leaves room for planning and corrections, CPU
time that a fast simulator turns into many seconds of sim time). A stopped clock stops the
limit too; the waits' own wall-clock caps and the controller's silence end such a goal.
:class:`GoalWatch` applies the limit and, every ``SENDER_CHECK`` s, asks whether the goal's
sender is still there (:mod:`flexarm_core.goal_sender`).
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_control.execution.modes import Mode
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_motion.arm_motion import MotionSettings

MAX_CORRECTIONS = 10
MAX_POSITION_TOLERANCE = 0.1               # [m]
MAX_ANGLE_TOLERANCE = math.radians(10.0)   # [rad]
TIME_MARGIN = 2.0
SENDER_CHECK = 0.5     # [s, wall] between two looks for a running goal's sender


@dataclass(frozen=True)
class GoalBounds:
    """The accepted ranges of a goal's tolerances and corrections (module docstring)."""

    min_position_tolerance: float   # [m]
    min_angle_tolerance: float      # [rad]
    max_position_tolerance: float = MAX_POSITION_TOLERANCE
    max_angle_tolerance: float = MAX_ANGLE_TOLERANCE
    max_corrections: int = MAX_CORRECTIONS

    @classmethod
    def from_settle(cls, settle: Mapping[str, Any]) -> GoalBounds:
        """Floors from the vision node's settledness criteria (config/vision.yaml
        ``settle.*``)."""
        return cls(float(settle['stability']), float(settle['angle_stability']))

    @classmethod
    def nominal(cls) -> GoalBounds:
        """The bounds of the shipped config/vision.yaml."""
        return cls.from_settle(load_config('vision.yaml', node_name='flexarm_vision')['settle'])

    def tolerance_error(self, position: float, angle: float) -> str | None:
        """Why tolerances (0: none given) are out of bounds, or None."""
        for name, value, low, high, unit in (
                ('position_tolerance', position, self.min_position_tolerance,
                 self.max_position_tolerance, 'm'),
                ('angle_tolerance', angle, self.min_angle_tolerance,
                 self.max_angle_tolerance, 'rad')):
            if value < 0:
                return f'{name} must be >= 0 (0 = server default), got {value:.6g} {unit}'
            if value and value < low:
                return (f'{name} {value:.6g} {unit} is below {low:.6g} {unit}, what the camera '
                        'tells apart (the vision\'s settledness): it could never be told met')
            if value > high:
                return (f'{name} {value:.6g} {unit} is beyond {high:.6g} {unit}: it would check '
                        'nothing (a unit slip?)')
        return None


def goal_error(target: Sequence[float], mode: int, position_tolerance: float,
               angle_tolerance: float, max_corrections: int, bounds: GoalBounds) -> str | None:
    """Why a goal is malformed or out of bounds (before any kinematics), or None."""
    values = {'target.x': target[0], 'target.y': target[1], 'target.phi': target[2],
              'position_tolerance': position_tolerance, 'angle_tolerance': angle_tolerance}
    bad = [name for name, v in values.items() if not math.isfinite(v)]
    if bad:
        return f'non-finite {", ".join(bad)}'
    if mode >= len(Mode):
        return f'unknown mode {mode}'
    if not -math.pi <= target[2] <= math.pi:
        return (f'target.phi {target[2]:.6g} rad is outside [-pi, pi]: give the angle itself, '
                'it is never wrapped')
    if max_corrections > bounds.max_corrections:
        return (f'max_corrections {max_corrections} is beyond {bounds.max_corrections} (0 = '
                'server default): more corrections do not mend a goal that keeps missing')
    return bounds.tolerance_error(position_tolerance, angle_tolerance)


def move_budget(geometry: ArmGeometry, motion: MotionSettings) -> float:
    """[s] the longest one move and its measurement may take within their own timeouts: both
    legs (the approach leg and the whole range of the slowest joint) and the measurement."""
    travel = float(np.max((geometry.upper - geometry.lower) / geometry.velocity))
    approach = float(np.max(np.abs(motion.approach) / geometry.velocity))
    return (travel + approach + 2 * motion.move_timeout_margin
            + motion.measurement_timeout)


def time_limit(moves: int, geometry: ArmGeometry, motion: MotionSettings) -> float:
    """[s, the arm's time] how long a goal of ``moves`` moves may hold the arm."""
    return TIME_MARGIN * moves * move_budget(geometry, motion)


class GoalWatch:
    """Whether the server ends a running goal itself, polled by the goal's waits like a cancel
    request: its time limit ran out (``elapsed()`` in the arm's time) or every client that
    may have sent it has left (``sender_left()``, asked every ``period`` s of wall time: it
    reads the graph). ``reason`` says why, once it has."""

    def __init__(self, limit: float, elapsed: Callable[[], float],
                 sender_left: Callable[[], bool], period: float = SENDER_CHECK,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.limit, self.reason = limit, ''
        self._elapsed, self._sender_left, self._period, self._clock = (
            elapsed, sender_left, period, clock)
        self._next_check = clock()

    def __call__(self) -> bool:
        if not self.reason:
            if self._elapsed() > self.limit:
                self.reason = (f"it outlasted its time limit, {self.limit:.0f} s of the arm's "
                               'time')
            elif self._clock() >= self._next_check:
                self._next_check = self._clock() + self._period
                if self._sender_left():
                    self.reason = 'every client that may have sent it has left the graph'
        return bool(self.reason)
