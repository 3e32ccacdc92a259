"""Where the tip camera sits on the tool: a correction of the measured tool pose (pure).

The vision node reports the tool pose through the believed camera mounting. A constant error of
the camera in the tool frame (principal point, mounting offset and yaw) moves every measured
pose by the same tool-frame vector and angle, and the learner learns the camera's pose, not the
tool's: a floor for every mode. A :class:`~flexarm_core.tool_correction.ToolCorrection`
removes such an error from every measurement; :func:`fit_reference` finds it from poses
measured by the camera and by a reference instrument at the same time (a laser tracker at
commissioning; the simulator's ground truth stands in for it): the mean tool-frame difference.

Why a reference and not the arm's own motions: a constant tool-frame error of the camera is
indistinguishable from the same error of the arm itself (link 4's length, joint 4's zero, a
lateral offset of the tool point), which the learner must learn, so no motion the arm makes
under its own camera can separate them. :func:`joint4_sweep` shows it: turning joint 4 alone,
the reported point traces an arc about the joint-4 axis, ``m_k = W + R(phi_k) c``, linear in W
and c; ``c - (link4, 0)`` should be the camera's offset along and across the tool axis, but it
also holds link 4's length error, reads a camera yaw as a lateral offset of ``-yaw x link4``,
and the axis W itself moves as the sag changes with the joint-4 angle (measured in
benchmarks/error_budget.py: the sweep's estimate is 1-2 mm off, for a 0.17 mm camera error).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.tool_correction import ToolCorrection


def fit_reference(measured: np.ndarray, reference: np.ndarray) -> ToolCorrection:
    """The correction that maps camera poses (n, 3) onto reference poses (n, 3) of the same
    moments, on average over the poses (n >= 1)."""
    measured, reference = (np.asarray(a, dtype=float).reshape(-1, 3)
                           for a in (measured, reference))
    if len(measured) == 0 or measured.shape != reference.shape:
        raise ValueError('a reference calibration needs as many reference as measured poses')
    d = measured[:, :2] - reference[:, :2]
    c, s = np.cos(reference[:, 2]), np.sin(reference[:, 2])
    axial, lateral = c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]
    angle = np.angle(np.exp(1j * (measured[:, 2] - reference[:, 2])).mean())
    return ToolCorrection(float(axial.mean()), float(lateral.mean()), float(angle))


@dataclass(frozen=True)
class ReferenceCalibration:
    """What :func:`calibrate_against_reference` found."""

    correction: ToolCorrection       # of the measurements as they were taken
    poses: int                       # pose pairs used
    spread: tuple[float, float]      # [m, rad] largest deviation of one pose's correction


def calibrate_against_reference(
        targets: Iterable[np.ndarray],
        measure: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray] | None],
) -> ReferenceCalibration:
    """``measure(target)`` moves the arm to each target and returns the (camera, reference)
    poses there, or None if either failed; the correction that fits them all. ValueError with
    fewer than 3 pose pairs: the spread over the poses is the calibration's check."""
    pairs = [pair for pair in map(measure, targets) if pair is not None]
    if len(pairs) < 3:
        raise ValueError(f'only {len(pairs)} poses were measured by both the camera and the '
                         'reference: 3 or more are needed')
    measured, reference = (np.array(side) for side in zip(*pairs))
    correction = fit_reference(measured, reference)
    each = [fit_reference(m, r) for m, r in pairs]
    position = max(math.hypot(e.axial - correction.axial, e.lateral - correction.lateral)
                   for e in each)
    angle = max(abs(e.angle - correction.angle) for e in each)
    return ReferenceCalibration(correction, len(pairs), (position, angle))


def sweep_joints(joints: np.ndarray, geometry: ArmGeometry, span: float = 0.5,
                 count: int = 9) -> np.ndarray:
    """``count`` copies of ``joints`` with joint 4 over ``span`` [rad] around its value, kept
    inside its limits (count, 4)."""
    low = max(joints[3] - span / 2, geometry.lower[3])
    high = min(joints[3] + span / 2, geometry.upper[3])
    sweep = np.repeat(np.asarray(joints, dtype=float)[None], count, axis=0)
    sweep[:, 3] = np.linspace(low, high, count)
    return sweep


def joint4_sweep(joints: np.ndarray, measured: np.ndarray, geometry: ArmGeometry
                 ) -> ToolCorrection:
    """The arc's estimate of the camera's offset (module docstring: not to be trusted) from
    measured poses (n, 3) at sweep ``joints`` (n, 4) that differ in joint 4 only; ValueError
    for fewer than 3 poses or a sweep of under 0.1 rad."""
    joints, measured = np.asarray(joints, dtype=float), np.asarray(measured, dtype=float)
    if len(measured) < 3 or np.ptp(joints[:, 3]) < 0.1:
        raise ValueError('a joint-4 sweep needs 3 poses or more over 0.1 rad or more')
    if np.any(np.ptp(joints[:, :3], axis=0) > 1e-9):
        raise ValueError('the sweep must hold joints 1 to 3')
    c, s = np.cos(measured[:, 2]), np.sin(measured[:, 2])
    one, zero = np.ones_like(c), np.zeros_like(c)
    # rows: x = Wx + c cx - s cy, y = Wy + s cx + c cy
    a = np.vstack([np.column_stack([one, zero, c, -s]), np.column_stack([zero, one, s, c])])
    b = np.concatenate([measured[:, 0], measured[:, 1]])
    solution = np.linalg.lstsq(a, b, rcond=None)[0]
    return ToolCorrection(float(solution[2] - geometry.link4), float(solution[3]))
