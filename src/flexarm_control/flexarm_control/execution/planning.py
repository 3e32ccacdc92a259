"""Goal planning policy of ``/move_to_pose`` (pure core of the compensator node): which plan a
goal runs, and when the model is not trusted.

* RIGID: the rigid inverse kinematics.
* PREDICTIVE: the compensated plan (:meth:`Compensator.predictive`), refused with
  ``OUTSIDE_LEARNED_DATA`` when the joints to command lie beyond the learned data — farther
  than ``max_distance`` typical sample spacings from the model's learning samples
  (:meth:`~flexarm_deflection.predictors.Predictor.data_distance`, any kind), or where the
  model's own standard deviation of the predicted tip position exceeds ``max_std``
  (:meth:`~flexarm_deflection.predictors.Predictor.position_std`, the GP) — unless the goal
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
* AUTO: PREDICTIVE where its plan's bound is within the goal's tolerance, else CLOSED_LOOP
  (:attr:`Planned.mode` says which, :attr:`Planned.note` why).

Every plan states the 95 % bound of the goal's true error before anything moves
(:attr:`Planned.bound`, :mod:`.plan_bound`), widened as the goals measured before it
say (``inflation``, :mod:`.bound_check`); NaN (none) for a model run at a payload it
cannot predict at (:func:`payload_beyond`, extrapolation allowed). A PREDICTIVE goal with a
tolerance its bound exceeds is refused (``BOUND_EXCEEDS_TOLERANCE``) with the bound and what
would help, unless it allows extrapolation: moving to learn it missed is what the bound is
there to prevent.

:class:`~flexarm_core.kinematics.UnreachableError` escapes for a target the rigid arm
cannot reach at all.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from flexarm_control.execution.bound_check import AS_CALIBRATED, BoundParts, Inflation
from flexarm_control.execution.compensator import CompensationError, Compensator, Plan
from flexarm_control.execution.modes import Mode
from flexarm_control.execution.plan_bound import RIGID_ERROR, SiteErrors
from flexarm_core.kinematics import inverse
from flexarm_deflection.at_payload import AtPayload
from flexarm_deflection.error_bound import Z_1D
from flexarm_deflection.predictors import Predictor
from flexarm_deflection.predictors.base import PAYLOAD_TOLERANCE


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
    bound: tuple[float, float] = (math.nan, math.nan)   # [m, rad] 95 % of the true error
    mode: Mode = Mode.RIGID    # the mode that runs (AUTO: the one it chose)
    parts: BoundParts | None = None    # PREDICTIVE with a model: the bound in its parts


@dataclass(frozen=True)
class Refusal:
    code: str              # 'no_model', 'unreachable', 'outside_learned_data', 'bound'
    reason: str
    bound: tuple[float, float] = (math.nan, math.nan)   # [m, rad] the plan's ('bound')


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
              allow_extrapolation: bool = False, trained_payloads: Sequence[float] = (),
              site: SiteErrors | None = None, tolerance: tuple[float, float] = (0.0, 0.0),
              inflation: Inflation = AS_CALIBRATED) -> Planned | Refusal:
    """The plan for a goal in ``mode`` (module docstring) with its bound, or why it is refused.

    ``trained_payloads``: the payloads [kg] of the model's samples; with them, ``predictor``
    is the model :class:`AtPayload` the arm carries now, checked by :func:`payload_beyond`
    (empty: not checked). ``site``: what no model sees (None: nothing). ``tolerance`` [m, rad]:
    the goal's (0: none; CLOSED_LOOP and AUTO need one). ``inflation``: the online bound's
    (:class:`~.bound_check.Inflation`)."""
    mode = Mode.of(mode)
    if mode == Mode.AUTO:
        return _auto(compensator, target, predictor, limits, trained_payloads, site, tolerance,
                     inflation)
    planned = _plan(compensator, mode, target, predictor, limits, allow_extrapolation,
                    trained_payloads)
    if isinstance(planned, Refusal):
        return planned
    blind = predictor is not None and bool(payload_beyond(predictor, trained_payloads))
    if blind and mode != Mode.CLOSED_LOOP:
        planned = replace(planned, mode=mode, bound=(math.nan, math.nan))
    else:
        planned = replace(planned, mode=mode, **_bound(compensator, mode, planned, predictor,
                                                       site, tolerance, inflation))
    if (mode == Mode.PREDICTIVE and not allow_extrapolation and max(tolerance) > 0
            and not all(b <= t for b, t in zip(planned.bound, tolerance) if t > 0)):
        if any(math.isnan(b) for b in planned.bound):
            return Refusal('bound', 'the model states no error bound (it was fitted without '
                                    "the learner's held-out calibration): train it again, or "
                                    'run CLOSED_LOOP or AUTO')
        return Refusal('bound', f"the plan's 95 % error bound, {_text(planned.bound)}, exceeds "
                                f'the tolerance {_text(tolerance)}{_help(predictor, planned)}',
                       planned.bound)
    return planned


def _text(values: tuple[float, float]) -> str:
    position, angle = values
    return f'{position * 1e3:.3f} mm, {math.degrees(angle):.4f} deg'


def _help(predictor: Predictor | AtPayload | None, planned: Planned) -> str:
    """What would bring the bound within a tolerance: the payload's samples where the masses'
    prior makes most of it, more samples where the model is unsure."""
    joints = planned.plan.joints
    prior = np.asarray(predictor.prior_std(joints)) if predictor is not None else np.zeros(3)
    if Z_1D * np.hypot(prior[0], prior[1]) > 0.5 * planned.bound[0]:
        return ('; most of it is the payload, which the samples do not show: collect samples '
                'carrying it (`flexarm refresh` or `flexarm collect`), or run CLOSED_LOOP or AUTO')
    return '; collect more samples here, or run CLOSED_LOOP or AUTO (they measure and correct)'


def _bound(compensator: Compensator, mode: Mode, planned: Planned,
           predictor: Predictor | AtPayload | None, site: SiteErrors | None,
           tolerance: tuple[float, float], inflation: Inflation) -> dict[str, Any]:
    """The plan's 95 % bound (:mod:`.plan_bound`) and, PREDICTIVE, its parts."""
    if mode == Mode.CLOSED_LOOP:
        position, angle = (site.closed_loop(tolerance) if site is not None
                           else np.asarray(tolerance))
        return {'bound': (float(position), float(angle))}
    if predictor is None:
        return {'bound': RIGID_ERROR}
    joints = planned.plan.joints
    parts = BoundParts(np.asarray(predictor.error_bound(joints), dtype=float),
                       site.at(compensator.geometry, joints) if site is not None
                       else np.zeros(2), inflation)
    if mode == Mode.PREDICTIVE:
        return {'bound': parts.stated, 'parts': parts}
    sag = np.asarray(predictor.predict(joints))        # RIGID: what the rigid plan leaves
    model = parts.stated
    return {'bound': (model[0] + math.hypot(sag[0], sag[1]), model[1] + abs(sag[2]))}


def _auto(compensator: Compensator, target: np.ndarray, predictor: Predictor | AtPayload | None,
          limits: DataLimits, trained_payloads: Sequence[float], site: SiteErrors | None,
          tolerance: tuple[float, float], inflation: Inflation) -> Planned | Refusal:
    """PREDICTIVE where it is bound within ``tolerance``, else CLOSED_LOOP, saying why."""
    if not min(tolerance) > 0:
        raise ValueError(f'AUTO needs a position and an angle tolerance, got {tolerance}')
    predictive = plan_goal(compensator, Mode.PREDICTIVE, target, predictor, limits,
                           trained_payloads=trained_payloads, site=site, tolerance=tolerance,
                           inflation=inflation)
    if isinstance(predictive, Planned):
        return replace(predictive, note='; '.join(filter(None, [
            f'AUTO ran PREDICTIVE: its 95 % bound {_text(predictive.bound)} is within the '
            f'tolerance', predictive.note])))
    closed = plan_goal(compensator, Mode.CLOSED_LOOP, target, predictor, limits,
                       trained_payloads=trained_payloads, site=site, tolerance=tolerance)
    if isinstance(closed, Refusal):
        return closed
    return replace(closed, note='; '.join(filter(None, [
        f'AUTO ran CLOSED_LOOP: {predictive.reason}', closed.note])))


def _plan(compensator: Compensator, mode: Mode, target: np.ndarray,
          predictor: Predictor | AtPayload | None, limits: DataLimits,
          allow_extrapolation: bool, trained_payloads: Sequence[float]) -> Planned | Refusal:
    """The plan of a RIGID, PREDICTIVE or CLOSED_LOOP goal without its bound."""
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
