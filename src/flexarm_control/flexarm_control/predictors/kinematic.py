"""Kinematic calibration as a predictor: what robot_calibration-style tools identify.

deflection(θ) = FK(θ + δθ; l3 + δl3, l4 + δl4, d + δd) − FK(θ; l3, l4, d): the joint zero
offsets δθ (4: rad, m, rad, rad) and the errors of the link lengths and the No.2 arm's lateral
offset (3, m) found by nonlinear least squares (``scipy.optimize.least_squares``) on the
samples, φ residuals weighted by ``ANGLE_LENGTH``, with a small ridge ``ridge`` × |p|² that
keeps parameters the poses do not tell apart (θ2 fixed: δθ2 and δl3 along one line) at the
smallest norm. The nominal geometry comes from config/arm.yaml at fit time and is kept in the
metadata (``kinematic.geometry``) with the identified parameters (``kinematic.parameters``):
a saved model is self-contained. Whatever is not rigid — the sag under gravity — it cannot
represent: on its own it is the baseline a user would try first; :mod:`.greybox` builds on it.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np
from scipy.optimize import least_squares

from flexarm_control.predictors.base import Predictor

ANGLE_LENGTH = 1.0     # [m] a φ residual of 1 rad weighs as much as 1 m of position
PARAMETERS = ('joint1_zero', 'joint2_zero', 'joint3_zero', 'joint4_zero', 'link3', 'link4',
              'offset')
KINEMATIC = len(PARAMETERS)


def nominal_geometry() -> dict[str, float]:
    """link3, link4 and offset [m] of config/arm.yaml."""
    from flexarm_control.params import load_config

    arm = load_config('arm.yaml')['arm']
    return {name: float(arm[name]) for name in ('link3', 'link4', 'offset')}


def perturbed_pose(geometry: Mapping[str, float], joints: np.ndarray, kinematic: np.ndarray,
                   turns: np.ndarray | None = None, shifts: np.ndarray | None = None,
                   ) -> np.ndarray:
    """Tip pose (N, 3) of the arm with kinematic errors ``kinematic`` (``PARAMETERS``) and, per
    sample, extra rotations ``turns`` (N, 4) [rad] at joint1, joint3, joint4 and of the tip
    frame only, and lateral displacements ``shifts`` (N, 3) [m] of joint3, joint4 and the tip
    (each normal to the link ending there); φ not wrapped."""
    q = np.asarray(joints, dtype=float) + kinematic[:4]
    turns = np.zeros((len(q), 4)) if turns is None else turns
    shifts = np.zeros((len(q), 3)) if shifts is None else shifts
    a1 = q[:, 0] + turns[:, 0]
    a3 = a1 + q[:, 2] + turns[:, 1]
    a4 = a3 + q[:, 3] + turns[:, 2]
    lateral = geometry['offset'] + kinematic[6] + shifts[:, 0]
    xy = np.zeros((len(q), 2))
    for angle, along, across in ((a1, q[:, 1], lateral),
                                 (a3, geometry['link3'] + kinematic[4], shifts[:, 1]),
                                 (a4, geometry['link4'] + kinematic[5], shifts[:, 2])):
        c, s = np.cos(angle), np.sin(angle)
        xy += np.column_stack([along * c - across * s, along * s + across * c])
    return np.column_stack([xy, a4 + turns[:, 3]])


def solve(residuals: Callable[[np.ndarray], np.ndarray], size: int, ridge: float
          ) -> np.ndarray:
    """Parameters (size,) minimising |residuals(p)|² + ridge |p|² from p = 0."""
    def objective(p: np.ndarray) -> np.ndarray:
        return np.concatenate([residuals(p), np.sqrt(ridge) * p])

    return least_squares(objective, np.zeros(size), method='trf', x_scale='jac').x


def weighted(error: np.ndarray) -> np.ndarray:
    """Deflection errors (N, 3) [m, m, rad] as one residual vector [m]."""
    return (error * np.array([1.0, 1.0, ANGLE_LENGTH])).ravel()


class KinematicPredictor(Predictor):
    """Joint zero offsets and link-length errors identified by least squares."""

    kind: ClassVar[str] = 'kinematic'
    defaults: ClassVar[dict[str, Any]] = {'ridge': 1e-8, 'payload_input': False}
    physical: ClassVar[bool] = True

    def _check_settings(self) -> None:
        if self.settings['ridge'] < 0:
            raise ValueError("kinematic 'ridge' must be >= 0")

    def _fit_physical(self, joints: np.ndarray, payload: np.ndarray | None,
                      deflections: np.ndarray) -> None:
        self._geometry = nominal_geometry()
        rigid = perturbed_pose(self._geometry, joints, np.zeros(KINEMATIC))
        self._parameters = solve(lambda p: weighted(
            perturbed_pose(self._geometry, joints, p) - rigid - deflections), KINEMATIC,
            self.settings['ridge'])
        self.metadata['kinematic'] = {'geometry': self._geometry, 'parameters': dict(
            zip(PARAMETERS, self._parameters.tolist()))}

    def _predict_physical(self, joints: np.ndarray, payload: np.ndarray | None) -> np.ndarray:
        return (perturbed_pose(self._geometry, joints, self._parameters)
                - perturbed_pose(self._geometry, joints, np.zeros(KINEMATIC)))

    def _state(self) -> dict[str, np.ndarray]:
        return {'parameters': self._parameters}

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        self._geometry = {name: float(value) for name, value in
                          self.metadata['kinematic']['geometry'].items()}
        self._parameters = np.asarray(state['parameters'], dtype=float).reshape(KINEMATIC)
