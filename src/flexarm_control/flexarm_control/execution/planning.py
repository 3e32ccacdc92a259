"""Goal planning policy of ``/move_to_pose`` (pure core of the compensator node): which plan a
goal runs, and when the model is not trusted.

* RIGID: the rigid inverse kinematics.
* PREDICTIVE: the compensated plan (:meth:`Compensator.predictive`), refused with
  ``OUTSIDE_LEARNED_DATA`` when the joints to command lie beyond the learned data — farther
  than ``max_distance`` typical sample spacings from the model's learning samples
  (:meth:`~flexarm_control.learning.predictors.Predictor.data_distance`, any kind), or where the
  model's own standard deviation of the predicted tip position exceeds ``max_std``
  (:meth:`~flexarm_control.learning.predictors.Predictor.position_std`, the GP) — unless the goal
  allows extrapolation, which runs it with a warning. Both are needed: a target 100 mm and 10°
  outside region B lies only ~1.3 spacings from the region's samples (targets inside reached 2.4),
  yet the GP misses it by 1 mm there, and its std says so (0.3 mm, against at most 0.25 mm inside).
  A plan the solver cannot find is refused as ``OUTSIDE_LEARNED_DATA`` when the target itself
  lies beyond the data (the likely cause), else ``UNREACHABLE``. The payload is learned data
  too: a model that neither takes it as an input nor carries it physically (a GP, MLP, RBF or
  kinematic model without ``payload_input``) predicts the sag of the payloads it was trained
  at, and is refused the same way when the arm carries another (:func:`payload_beyond`): 5 kg
  more than trained, its prediction misses by up to 18 mm. The grey-box carries the payload
  through its gravity moments; a model with the payload input counts it in its data
  distance.
* CLOSED_LOOP: the PREDICTIVE plan when there is one to trust; without a model, when the
  prediction cannot be planned or lies beyond the learned data, it starts from the rigid
  plan — it measures the tip and corrects, so it needs no model to converge, only more moves.

:class:`~flexarm_core.kinematics.UnreachableError` escapes for a target the rigid arm
cannot reach at all.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from flexarm_control.execution.compensator import CompensationError, Compensator, Plan
from flexarm_control.execution.modes import Mode
from flexarm_control.learning.at_payload import AtPayload
from flexarm_control.learning.predictors import Predictor
from flexarm_core.kinematics import inverse

# [kg] a payload this close to a trained one counts as that one: the tip sags at most 3.6 mm
# per kg over the learner's regions (simulated arm), so 10 g is <= 0.04 mm, the joints'
# repeatability at the tip; payloads are declared to a gram or two.
PAYLOAD_TOLERANCE = 0.01


@dataclass(frozen=True)
class DataLimits:
    max_distance: float    # [typical sample spacings]
    max_std: float         # [m] of the predicted tip position


@dataclass(frozen=True)
class Planned:
    plan: Plan
    data_distance: float   # of plan.joints from the learned data (0 when no model is used)
    prediction_std: float  # [m] the model's std of the predicted tip position there
    note: str              # warning or fallback for the operator ('' if none)
    uses_model: bool = False   # whether the plan came from the predictor (not the rigid one)
    extrapolated: bool = False  # the model predicts beyond its learned data (goal allowed it)


@dataclass(frozen=True)
class Refusal:
    code: str              # 'no_model', 'unreachable' or 'outside_learned_data'
    reason: str


def beyond_data(predictor: Predictor, joints: np.ndarray, limits: DataLimits
                ) -> tuple[float, float, str]:
    """(data distance, position std [m], why ``joints`` lie beyond the data or '')."""
    distance = predictor.data_distance(joints)
    std = predictor.position_std(joints)
    why = []
    if distance > limits.max_distance:
        why.append(f'{distance:.2f} sample spacings from the learning samples (limit '
                   f'{limits.max_distance:g})')
    if std > limits.max_std:
        why.append(f'the model is unsure there (std {std * 1e3:.3f} mm, limit '
                   f'{limits.max_std * 1e3:g} mm)')
    return distance, std, ' and '.join(why)


def payload_beyond(predictor: AtPayload, trained: Sequence[float]) -> str:
    """Why ``predictor`` cannot predict at the payload it is seen at, having been trained at
    ``trained`` [kg] ('' if it can: it carries the payload, a trained one is within
    ``PAYLOAD_TOLERANCE``, or ``trained`` is unknown, empty)."""
    if not trained or predictor.carried or any(
            abs(p - predictor.payload) <= PAYLOAD_TOLERANCE for p in trained):
        return ''
    listed = ', '.join(f'{p:g}' for p in sorted(trained))
    return (f'the model, trained at payloads [{listed}] kg, cannot predict at '
            f'{predictor.payload:g} kg (it neither takes the payload as an input nor models it)')


def plan_goal(compensator: Compensator, mode: Mode | str, target: np.ndarray,
              predictor: Predictor | AtPayload | None, limits: DataLimits,
              allow_extrapolation: bool = False,
              trained_payloads: Sequence[float] = ()) -> Planned | Refusal:
    """The plan for a goal in ``mode`` (module docstring), or why it is refused.

    ``trained_payloads``: the payloads [kg] of the model's samples; with them, ``predictor``
    is the model :class:`AtPayload` the arm carries now, checked by :func:`payload_beyond`
    (empty: not checked)."""
    mode = Mode.of(mode)
    if mode == Mode.RIGID:
        return Planned(compensator.rigid(target), 0.0, 0.0, '')
    closed = mode == Mode.CLOSED_LOOP

    def rigid_start(why: str, distance: float = 0.0, std: float = 0.0) -> Planned:
        return Planned(compensator.rigid(target), distance, std,
                       f'{why}: CLOSED_LOOP started from the rigid solution')

    if predictor is None:
        return (rigid_start('no trained model') if closed
                else Refusal('no_model', 'no trained predictor yet: collect samples and train'))
    payload = payload_beyond(predictor, trained_payloads)
    try:
        plan = compensator.predictive(target, predictor.predict)
    except CompensationError as exc:
        distance, std, why = beyond_data(
            predictor, inverse(compensator.geometry, target), limits)
        why = ' and '.join(filter(None, [why, payload]))
        if closed:
            return rigid_start(f'prediction failed ({exc})', distance, std)
        if why:
            return Refusal('outside_learned_data', f'{exc}; the target lies beyond the '
                           f'learned data: {why}')
        return Refusal('unreachable', str(exc))
    distance, std, why = beyond_data(predictor, plan.joints, limits)
    if not (why or payload):
        return Planned(plan, distance, std, '', uses_model=True)
    beyond = '; '.join(filter(None, [
        why and f'the joints to command lie beyond the learned data: {why}', payload]))
    if allow_extrapolation:
        return Planned(plan, distance, std, f'warning: {beyond}; extrapolated, the prediction '
                                            'may be wrong there', uses_model=True,
                       extrapolated=True)
    if closed:
        return rigid_start(beyond, distance, std)
    where = ' and '.join(filter(None, [why and 'there', payload and 'at this payload']))
    return Refusal('outside_learned_data', f'{beyond}; collect samples {where}, or allow '
                                           'extrapolation')
