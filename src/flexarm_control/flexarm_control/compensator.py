"""Position compensation (seed section 3-2, Fig. 4): where to command the rigid model so the
flexible arm's tip lands on the target.

* RIGID: θ = IK(x_d).
* PREDICTIVE (the paper): θ0 = IK(x_d); x*_{k+1} = x_d − Δ(θ_k), θ_{k+1} = IK(x*_{k+1}),
  repeated until x* moves less than ``tolerance`` (fixed point x* = x_d − Δ(IK(x*))); an
  iteration still moving more than that after ``max_iterations`` is refused.
* CLOSED_LOOP (beyond the paper): after a move, the measured error corrects the commanded
  pose, x* ← x* + gain·(x_d − x_measured), and the arm moves again.

Convergence. The tip actually reached when commanding x* is F(x*) = x* + Δ(IK(x*)); the
iteration contracts when, for a small change of x*, the actual tip displacement a differs from
the rigid-model displacement r by less than |r|: |a − r| < |r|. For |a| = |r| that is an angle
between them under 60°, and for a ∥ r that is |a| < 2|r| — the two conditions of section 3-2.
The predicted deflection of a real arm changes by far less than the motion (|Δ'| ≪ 1), so a
few iterations suffice; an iteration whose steps grow is reported as divergence.

θ2 (redundant) follows :func:`flexarm_control.kinematics.inverse`'s rule for the target and is
then kept for the compensated poses, falling back to the rule only when the kept extension
cannot reach them. Pure numpy; ``predict`` is any callable joints (4,) → deflection (3,).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_control.kinematics import ArmGeometry, UnreachableError, inverse, wrap_angle

Predict = Callable[[np.ndarray], np.ndarray]


class CompensationError(UnreachableError):
    """The compensated target cannot be reached or the fixed-point iteration diverges or
    does not converge."""


@dataclass(frozen=True)
class Plan:
    joints: np.ndarray                # (4,) to command
    commanded_pose: np.ndarray        # (3,) x* given to the rigid inverse kinematics
    predicted_deflection: np.ndarray  # (3,) Δ(θ) at the commanded joints (0 for RIGID)
    iterations: int                   # fixed-point iterations run (0 for RIGID)
    step: float                       # last change of x* [m, position part]


@dataclass(frozen=True)
class CompensationSettings:
    max_iterations: int   # of the fixed point (>= 2: convergence is judged from the second)
    tolerance: float      # [m] converged when x* moves less than this (position part)
    gain: float           # closed-loop correction gain (1 = full measured error)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CompensationSettings:
        s = cls(int(d['max_iterations']), float(d['tolerance']), float(d['gain']))
        if s.max_iterations < 2 or s.tolerance <= 0 or not 0 < s.gain <= 1.5:
            raise ValueError(f'invalid compensation settings {s}')
        return s


class Compensator:
    """Plans joint commands for a target pose in the three modes."""

    def __init__(self, geometry: ArmGeometry, settings: Mapping[str, Any]) -> None:
        self.geometry = geometry
        self.settings = CompensationSettings.from_dict(settings)

    def _inverse(self, pose: np.ndarray, extension: float) -> np.ndarray:
        try:
            return inverse(self.geometry, pose, extension)
        except UnreachableError:
            return inverse(self.geometry, pose)

    def rigid(self, target: np.ndarray) -> Plan:
        target = np.asarray(target, dtype=float)
        return Plan(inverse(self.geometry, target), target, np.zeros(3), 0, 0.0)

    def predictive(self, target: np.ndarray, predict: Predict) -> Plan:
        """The paper's iteration to its fixed point; raises :class:`CompensationError`."""
        target = np.asarray(target, dtype=float)
        joints = inverse(self.geometry, target)
        extension = joints[1]
        commanded, steps = target, []
        for iteration in range(1, self.settings.max_iterations + 1):
            deflection = np.asarray(predict(joints), dtype=float)
            new = target - deflection
            new[2] = wrap_angle(new[2])
            try:
                joints = self._inverse(new, extension)
            except UnreachableError as exc:
                raise CompensationError(f'compensated target unreachable: {exc}') from exc
            steps.append(float(np.hypot(*(new[:2] - commanded[:2]))))
            commanded = new
            if iteration > 1 and steps[-1] < self.settings.tolerance:
                break
        if len(steps) > 2 and steps[-1] > steps[1]:
            raise CompensationError(
                f'compensation diverges (steps {steps[1] * 1e3:.3g} -> {steps[-1] * 1e3:.3g} mm):'
                ' the predicted deflection changes faster than the motion (section 3-2)')
        if not steps[-1] < self.settings.tolerance:
            raise CompensationError(
                f'compensation does not converge: x* still moves {steps[-1] * 1e3:.3g} mm after '
                f'{len(steps)} iterations (tolerance {self.settings.tolerance * 1e3:.3g} mm)')
        return Plan(joints, commanded, np.asarray(predict(joints), dtype=float), len(steps),
                    steps[-1])

    def correct(self, plan: Plan, target: np.ndarray, measured: np.ndarray) -> Plan:
        """Closed-loop step: shift the commanded pose by the measured error."""
        error = np.asarray(target, dtype=float) - np.asarray(measured, dtype=float)
        error[2] = wrap_angle(error[2])
        commanded = plan.commanded_pose + self.settings.gain * error
        commanded[2] = wrap_angle(commanded[2])
        try:
            joints = self._inverse(commanded, plan.joints[1])
        except UnreachableError as exc:
            raise CompensationError(f'corrected target unreachable: {exc}') from exc
        return Plan(joints, commanded, plan.predicted_deflection, plan.iterations,
                    float(np.hypot(*(self.settings.gain * error[:2]))))
