"""Goal planning policy of ``/move_to_pose`` (pure core of the compensator node): which plan a
goal runs, and when the model is not trusted.

* RIGID: the rigid inverse kinematics.
* PREDICTIVE: the compensated plan (:meth:`Compensator.predictive`). Refused with
  ``OUTSIDE_LEARNED_DATA`` when the joints to command lie farther than ``max_distance`` typical
  sample spacings from the model's learning samples
  (:meth:`~flexarm_control.predictors.Predictor.data_distance`) — the prediction there is a
  guess, and a guess can miss by millimetres — unless the goal allows extrapolation, which
  runs it with a warning. A plan the solver cannot find is refused as ``OUTSIDE_LEARNED_DATA``
  when the target itself lies beyond the data (the likely cause), else ``UNREACHABLE``.
* CLOSED_LOOP: the PREDICTIVE plan when there is one to trust; without a model, when the
  prediction cannot be planned or lies beyond the learned data, it starts from the rigid
  plan — it measures the tip and corrects, so it needs no model to converge, only more moves.

:class:`~flexarm_control.kinematics.UnreachableError` escapes for a target the rigid arm
cannot reach at all.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flexarm_control.compensator import CompensationError, Compensator, Plan
from flexarm_control.kinematics import inverse
from flexarm_control.predictors import Predictor

MODES = ('rigid', 'predictive', 'closed_loop')


@dataclass(frozen=True)
class Planned:
    plan: Plan
    data_distance: float   # of plan.joints from the learned data (0 when no model is used)
    note: str              # warning or fallback for the operator ('' if none)


@dataclass(frozen=True)
class Refusal:
    code: str              # 'no_model', 'unreachable' or 'outside_learned_data'
    reason: str


def plan_goal(compensator: Compensator, mode: str, target: np.ndarray,
              predictor: Predictor | None, max_distance: float,
              allow_extrapolation: bool = False) -> Planned | Refusal:
    """The plan for a goal in ``mode`` (module docstring), or why it is refused."""
    if mode not in MODES:
        raise ValueError(f'unknown mode {mode!r}')
    if mode == 'rigid':
        return Planned(compensator.rigid(target), 0.0, '')
    closed = mode == 'closed_loop'

    def rigid_start(why: str, distance: float = 0.0) -> Planned:
        return Planned(compensator.rigid(target), distance,
                       f'{why}: CLOSED_LOOP started from the rigid solution')

    if predictor is None:
        return (rigid_start('no trained model') if closed
                else Refusal('no_model', 'no trained predictor yet: collect samples and train'))
    try:
        plan = compensator.predictive(target, predictor.predict)
    except CompensationError as exc:
        distance = predictor.data_distance(inverse(compensator.geometry, target))
        if closed:
            return rigid_start(f'prediction failed ({exc})', distance)
        if distance > max_distance:
            return Refusal('outside_learned_data', f'{exc}; the target lies {distance:.1f} '
                           f'sample spacings from the learned data (limit {max_distance:g})')
        return Refusal('unreachable', str(exc))
    distance = predictor.data_distance(plan.joints)
    if distance <= max_distance:
        return Planned(plan, distance, '')
    beyond = (f'the joints to command lie {distance:.2f} sample spacings from the learned '
              f'data (limit {max_distance:g})')
    if allow_extrapolation:
        return Planned(plan, distance, f'warning: {beyond}; extrapolated, the prediction may '
                                       'be wrong there')
    if closed:
        return rigid_start(beyond, distance)
    return Refusal('outside_learned_data', f'{beyond}: collect samples there, or allow '
                                           'extrapolation')
