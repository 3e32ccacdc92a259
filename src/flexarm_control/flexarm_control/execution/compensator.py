"""Position compensation (paper section 3-2, Fig. 4): where to command the rigid model so the
flexible arm's tip lands on the target.

* RIGID: θ = IK(x_d).
* PREDICTIVE: the fixed point x* = x_d − Δ(IK(x*)) of the paper, i.e. the joints θ at which
  the predicted tip FK(θ) + Δ(θ) is the target, commanded as x* = FK(θ). Two solvers
  (``method``):

  - ``newton`` (default): θ2 is chosen once, by the kinematics' rule for the first
    compensated pose x_d − Δ(IK(x_d)) (its ``reach_margin`` covers the rest of the way), and
    kept; joints 1, 3, 4 solve FK(θ) + Δ(θ) = x_d by damped Newton steps with the
    predictor's Jacobian (finite differences, in the same predictor call as the point) and a
    backtracking line search. It converges wherever the fixed point exists and the predicted
    deflection does not cancel the motion (I + dΔ/dx* regular), also where the paper's
    iteration oscillates.
  - ``paper``: x*_{k+1} = x_d − Δ(θ_k), θ_{k+1} = IK(x*_{k+1}), the iteration of section
    3-2, kept for the comparison with Tables 9 and 10. It contracts only when, for a small
    change of x*, the actual tip displacement a differs from the rigid-model one r by less
    than |r| (the section's two conditions); steps that grow are reported as divergence.

  Converged when the predicted tip is within ``tolerance`` [m] and ``angle_tolerance``
  [rad] of the target (newton), or x* moves less than that (paper); anything else after
  ``max_iterations`` is refused, as is a solution outside the joint limits or with the elbow
  straighter than ``min_elbow_bend``.
* CLOSED_LOOP (beyond the paper): after a move, the measured error corrects the commanded
  pose, x* ← x* + gain·(x_d − x_measured), and the arm moves again, θ2 kept.

Pure numpy; ``predict`` is any callable joints (4,) or (M, 4) → deflection (3,) or (M, 3).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from flexarm_core.kinematics import (
    ArmGeometry,
    UnreachableError,
    elbow_bend,
    forward,
    inverse,
    limit_violation,
    wrap_angle,
)
from flexarm_deflection.deflection_slope import FREE, JACOBIAN_STEP, Predict

METHODS = ('newton', 'paper')
MIN_STEP_FRACTION = 1 / 64  # line search: smallest fraction of a Newton step tried


class _Point(NamedTuple):
    """What the Newton solver knows of joints q."""

    residual: np.ndarray     # (3,) predicted tip FK(q) + Δ(q) − target, angle wrapped
    jacobian: np.ndarray     # (3, 3) of the residual by the free joints
    deflection: np.ndarray   # (3,) Δ(q)
    pose: np.ndarray         # (3,) FK(q), the pose to command


class CompensationError(UnreachableError):
    """The compensated target cannot be reached, or the solver finds no fixed point (it
    diverges, does not converge, or the predicted deflection cancels the motion)."""


@dataclass(frozen=True)
class Plan:
    joints: np.ndarray                # (4,) to command
    commanded_pose: np.ndarray        # (3,) x* given to the rigid inverse kinematics
    predicted_deflection: np.ndarray  # (3,) Δ(θ) at the commanded joints (0 for RIGID)
    iterations: int                   # fixed-point iterations run (0 for RIGID)
    step: float                       # last change of x* [m, position part]


@dataclass(frozen=True)
class CompensationSettings:
    method: str             # 'newton' or 'paper' (module docstring)
    max_iterations: int     # of the solver (>= 2: the paper's is judged from the second)
    tolerance: float        # [m] position part of the convergence test
    angle_tolerance: float  # [rad] angle part (newton)
    gain: float             # closed-loop correction gain (1 = full measured error)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CompensationSettings:
        s = cls(str(d.get('method', 'newton')), int(d['max_iterations']),
                float(d['tolerance']), float(d.get('angle_tolerance', d['tolerance'])),
                float(d['gain']))
        if (s.method not in METHODS or s.max_iterations < 2 or s.tolerance <= 0
                or s.angle_tolerance <= 0 or not 0 < s.gain <= 1.5):
            raise ValueError(f'invalid compensation settings {s} (method: one of {METHODS})')
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
        """Joints whose predicted tip is on ``target`` (module docstring); raises
        :class:`CompensationError` (or :class:`UnreachableError` for the target itself)."""
        if self.settings.method == 'paper':
            return self._paper(np.asarray(target, dtype=float), predict)
        return self._newton(np.asarray(target, dtype=float), predict)

    def _newton(self, target: np.ndarray, predict: Predict) -> Plan:
        first = target - np.asarray(predict(inverse(self.geometry, target)), dtype=float)
        first[2] = wrap_angle(first[2])
        try:
            joints = inverse(self.geometry, first)
        except UnreachableError as exc:
            raise CompensationError(f'compensated target unreachable: {exc}') from exc
        branch = np.sign(elbow_bend(self.geometry, joints))
        weight = np.array([1.0, 1.0, self.geometry.link4])   # angle as tip-length metres
        probes = np.zeros((1 + len(FREE), 4))
        probes[np.arange(1, 1 + len(FREE)), FREE] = JACOBIAN_STEP

        def evaluate(q: np.ndarray) -> _Point:
            """The solver's view of joints q from one predictor call (whose cost dominates)
            for q and its finite-difference probes."""
            batch = q + probes
            deflection = np.asarray(predict(batch), dtype=float)
            pose = forward(self.geometry, batch)
            r = pose + deflection - target
            r[:, 2] = wrap_angle(r[:, 2])
            return _Point(r[0], ((r[1:] - r[0]) / JACOBIAN_STEP).T, deflection[0], pose[0])

        point, step, iterations = evaluate(joints), 0.0, 0
        while not (np.hypot(*point.residual[:2]) <= self.settings.tolerance
                   and abs(point.residual[2]) <= self.settings.angle_tolerance):
            r = point.residual
            if iterations == self.settings.max_iterations:
                raise CompensationError(
                    f'compensation does not converge: the predicted tip is still '
                    f'{np.hypot(r[0], r[1]) * 1e3:.3g} mm / {np.degrees(abs(r[2])):.3g} deg '
                    f'from the target after {iterations} Newton steps')
            iterations += 1
            try:
                direction = np.linalg.solve(point.jacobian, -r)
            except np.linalg.LinAlgError:
                direction = np.full(len(FREE), np.nan)
            fraction, size = 1.0, np.linalg.norm(r * weight)
            while True:
                trial = joints.copy()
                trial[FREE] += fraction * direction
                tried = evaluate(trial)
                if np.linalg.norm(tried.residual * weight) < (1 - 1e-4 * fraction) * size:
                    break
                fraction /= 2
                if not fraction >= MIN_STEP_FRACTION:   # also for a NaN direction
                    raise CompensationError(
                        'compensation has no solution here: the predicted deflection cancels '
                        f'the motion (the predicted tip stays {np.hypot(r[0], r[1]) * 1e3:.3g}'
                        ' mm from the target); the model is unreliable at this pose')
            step = float(np.hypot(*(tried.pose[:2] - point.pose[:2])))
            joints, point = trial, tried
        deflection = point.deflection
        wrapped = joints.copy()
        wrapped[FREE] = wrap_angle(joints[FREE])
        if np.abs(wrapped - joints).max() > np.pi:    # a turn, not rounding: predict there
            deflection = np.asarray(predict(wrapped), dtype=float)
        joints = wrapped
        violation = limit_violation(self.geometry, joints)
        if violation is not None:
            raise CompensationError(f'compensated target unreachable: {violation}')
        bend = elbow_bend(self.geometry, joints)
        if np.sign(bend) != branch or abs(bend) < self.geometry.min_elbow_bend:
            raise CompensationError(
                f'compensated target unreachable: the elbow would bend {np.degrees(bend):.2f} '
                f'deg (at least {np.degrees(self.geometry.min_elbow_bend):.1f} deg, same '
                'branch)')
        return Plan(joints, point.pose, deflection, iterations, step)

    def _paper(self, target: np.ndarray, predict: Predict) -> Plan:
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
