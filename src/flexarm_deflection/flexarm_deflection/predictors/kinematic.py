"""Kinematic calibration as a predictor: what robot_calibration-style tools identify.

deflection(θ) = FK(θ + δθ; l3 + δl3, l4 + δl4, d + δd) − FK(θ; l3, l4, d): the joint zero
offsets δθ (4: rad, m, rad, rad) and the errors of the link lengths and the No.2 arm's lateral
offset (3, m) found by nonlinear least squares (``scipy.optimize.least_squares``) on the
samples, φ residuals weighted by ``ANGLE_LENGTH``, with a small ridge ``ridge`` × |p|² that
keeps parameters the poses do not tell apart (θ2 fixed: δθ2 and δl3 along one line) at the
smallest norm. The nominal geometry comes from config/arm.yaml at fit time and is kept in the
metadata (``kinematic.geometry``) with the identified parameters (``kinematic.parameters``):
a saved model is self-contained. Their Gauss-Newton covariance (:func:`covariance`) gives
the raw std of a prediction (:meth:`KinematicPredictor.deflection_std`). Whatever is not
rigid — the sag under gravity — it cannot represent: on its own it is the baseline a user
would try first; :mod:`.greybox` builds on it.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np

from flexarm_deflection.predictors.base import Predictor

ANGLE_LENGTH = 1.0     # [m] a φ residual of 1 rad weighs as much as 1 m of position
PARAMETERS = ('joint1_zero', 'joint2_zero', 'joint3_zero', 'joint4_zero', 'link3', 'link4',
              'offset')
KINEMATIC = len(PARAMETERS)
_CONFIGS: dict[tuple[str, ...], tuple[tuple[int, ...], dict[str, Any]]] = {}


def read_config(*names: str) -> dict[str, Any]:
    """``load_config(*names)``, parsed again only when one of the files changed (shared: not
    to be modified). Parsing the YAML (~15 ms) took longer than fitting a kinematic model,
    and a cross-validation fits tens of models."""
    from flexarm_core.params import config_path, load_config

    stamps = tuple(config_path(name).stat().st_mtime_ns for name in names)
    cached = _CONFIGS.get(names)
    if cached is None or cached[0] != stamps:
        cached = _CONFIGS[names] = (stamps, load_config(*names))
    return cached[1]


def nominal_geometry() -> dict[str, float]:
    """link3, link4 and offset [m] of config/arm.yaml."""
    arm = read_config('arm.yaml')['arm']
    return {name: float(arm[name]) for name in ('link3', 'link4', 'offset')}


def _links(geometry: Mapping[str, float], joints: np.ndarray, kinematic: np.ndarray,
           turns: np.ndarray | None, shifts: np.ndarray | None,
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per sample and link (No.2 arm, third, fourth; (N, 3)): its angle, its length along it
    and its lateral offset; and the tip angle (N,), for :func:`perturbed_pose`."""
    q = np.asarray(joints, dtype=float) + kinematic[:4]
    angles = np.cumsum(q[:, [0, 2, 3]] if turns is None else q[:, [0, 2, 3]] + turns[:, :3],
                       axis=1)
    along = np.empty_like(angles)
    along[:, 0] = q[:, 1]
    along[:, 1:] = geometry['link3'] + kinematic[4], geometry['link4'] + kinematic[5]
    across = np.zeros_like(angles) if shifts is None else shifts.copy()
    across[:, 0] += geometry['offset'] + kinematic[6]
    return angles, along, across, angles[:, 2] if turns is None else angles[:, 2] + turns[:, 3]


def perturbed_pose(geometry: Mapping[str, float], joints: np.ndarray, kinematic: np.ndarray,
                   turns: np.ndarray | None = None, shifts: np.ndarray | None = None,
                   ) -> np.ndarray:
    """Tip pose (N, 3) of the arm with kinematic errors ``kinematic`` (``PARAMETERS``) and, per
    sample, extra rotations ``turns`` (N, 4) [rad] at joint1, joint3, joint4 and of the tip
    frame only, and lateral displacements ``shifts`` (N, 3) [m] of joint3, joint4 and the tip
    (each normal to the link ending there); φ not wrapped."""
    angles, along, across, phi = _links(geometry, joints, kinematic, turns, shifts)
    c, s = np.cos(angles), np.sin(angles)
    return np.stack([(along * c - across * s).sum(axis=1), (along * s + across * c).sum(axis=1),
                     phi], axis=1)


def pose_change(geometry: Mapping[str, float], joints: np.ndarray, kinematic: np.ndarray,
                turns: np.ndarray | None = None, shifts: np.ndarray | None = None,
                ) -> np.ndarray:
    """:func:`perturbed_pose` minus the rigid pose (N, 3), the deflection the physical kinds
    predict, with one pass over the sines and cosines of both (the compensator queries it
    in its inner loop)."""
    angles, along, across, phi = _links(geometry, joints, kinematic, turns, shifts)
    rigid, rigid_along, rigid_across, rigid_phi = _links(geometry, joints, np.zeros(KINEMATIC),
                                                         None, None)
    both = np.concatenate([angles, rigid], axis=1)
    along = np.concatenate([along, -rigid_along], axis=1)
    across = np.concatenate([across, -rigid_across], axis=1)
    c, s = np.cos(both), np.sin(both)
    return np.stack([(along * c - across * s).sum(axis=1), (along * s + across * c).sum(axis=1),
                     phi - rigid_phi], axis=1)


def pose_jacobian(geometry: Mapping[str, float], joints: np.ndarray, kinematic: np.ndarray,
                  turns: np.ndarray | None = None, shifts: np.ndarray | None = None,
                  ) -> np.ndarray:
    """Derivatives (N, 3, 14) of :func:`perturbed_pose` by the kinematic errors (7), the turns
    (4) and the shifts (3): analytic, so that least squares needs no finite differences (one
    pose per step instead of one per parameter)."""
    angles, along, across, _ = _links(geometry, joints, kinematic, turns, shifts)
    c, s = np.cos(angles), np.sin(angles)
    # A turn at joint1, joint3 or joint4 turns the links from there on: (-y, x) of their sum.
    beyond_x = np.cumsum((along * c - across * s)[:, ::-1], axis=1)[:, ::-1]
    beyond_y = np.cumsum((along * s + across * c)[:, ::-1], axis=1)[:, ::-1]
    jac = np.zeros((len(angles), 3, KINEMATIC + 7))
    jac[:, 0, KINEMATIC:KINEMATIC + 3], jac[:, 1, KINEMATIC:KINEMATIC + 3] = -beyond_y, beyond_x
    jac[:, 2, KINEMATIC:KINEMATIC + 4] = 1.0
    jac[:, 0, KINEMATIC + 4:], jac[:, 1, KINEMATIC + 4:] = -s, c      # shifts: across a link
    jac[:, 0, [1, 4, 5]], jac[:, 1, [1, 4, 5]] = c, s                # lengths: along a link
    jac[:, :, [0, 2, 3, 6]] = jac[:, :, KINEMATIC + np.array([0, 1, 2, 4])]
    return jac


def solve(residuals: Callable[[np.ndarray], np.ndarray],
          jacobian: Callable[[np.ndarray], np.ndarray], size: int, ridge: float) -> np.ndarray:
    """Parameters (size,) minimising |residuals(p)|² + ridge |p|² from p = 0, with the
    residuals' ``jacobian`` (len(residuals), size), by Levenberg-Marquardt (MINPACK): on the
    grey-box of a sag it does not model, the trust-region reflective solver crept for ~750
    steps where this takes ~45, to the same or a lower cost."""
    def objective(p: np.ndarray) -> np.ndarray:
        return np.concatenate([residuals(p), np.sqrt(ridge) * p])

    def derivative(p: np.ndarray) -> np.ndarray:
        return np.vstack([jacobian(p), np.sqrt(ridge) * np.eye(size)])

    from scipy.optimize import least_squares

    return least_squares(objective, np.zeros(size), derivative, method='lm', x_scale='jac').x


def covariance(jacobian: np.ndarray, residuals: np.ndarray, ridge: float) -> np.ndarray:
    """Gauss-Newton covariance (P, P) of least-squares parameters at their optimum, from the
    residuals' Jacobian (R, P) and the residuals (R,) there: σ² (JᵀJ + ridge)⁺, σ² their
    variance over R - P degrees of freedom (at least one). Directions the samples do not
    tell apart (and the ridge decides) get none: the pseudo-inverse drops them, as the
    solution does."""
    rows, size = jacobian.shape
    variance = float(residuals @ residuals) / max(rows - size, 1)
    return variance * np.linalg.pinv(jacobian.T @ jacobian + ridge * np.eye(size),
                                     rcond=1e-10, hermitian=True)


def propagated_std(jacobian: np.ndarray, parameter_covariance: np.ndarray) -> np.ndarray:
    """Std (N, 3) of outputs whose derivatives by the parameters are ``jacobian``
    (N, 3, P)."""
    variance = np.einsum('nop,pq,noq->no', jacobian, parameter_covariance, jacobian)
    return np.sqrt(np.maximum(variance, 0.0))


def weighted(error: np.ndarray) -> np.ndarray:
    """Deflection errors (N, 3) [m, m, rad], or their derivatives (N, 3, P), as one residual
    vector [m] (or its Jacobian (3N, P))."""
    scaled = error * np.array([1.0, 1.0, ANGLE_LENGTH]).reshape(3, *([1] * (error.ndim - 2)))
    return scaled.reshape(-1, *error.shape[2:])


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

        def residuals(p: np.ndarray) -> np.ndarray:
            return weighted(perturbed_pose(self._geometry, joints, p) - rigid - deflections)

        def jacobian(p: np.ndarray) -> np.ndarray:
            return weighted(pose_jacobian(self._geometry, joints, p)[:, :, :KINEMATIC])

        ridge = self.settings['ridge']
        self._parameters = solve(residuals, jacobian, KINEMATIC, ridge)
        self._covariance = covariance(jacobian(self._parameters), residuals(self._parameters),
                                      ridge)
        self.metadata['kinematic'] = {'geometry': self._geometry, 'parameters': dict(
            zip(PARAMETERS, self._parameters.tolist()))}

    def _predict_physical(self, joints: np.ndarray, payload: np.ndarray | None) -> np.ndarray:
        return pose_change(self._geometry, joints, self._parameters)

    def deflection_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                       ) -> np.ndarray:
        """From the identified parameters' covariance (:func:`covariance`)."""
        q, _, single = self._query(joints, payload)
        self._require_fitted()
        std = propagated_std(pose_jacobian(self._geometry, q, self._parameters)[:, :, :KINEMATIC],
                             self._covariance)
        return std[0] if single else std

    def _state(self) -> dict[str, np.ndarray]:
        return {'parameters': self._parameters, 'covariance': self._covariance}

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        self._geometry = {name: float(value) for name, value in
                          self.metadata['kinematic']['geometry'].items()}
        self._parameters = np.asarray(state['parameters'], dtype=float).reshape(KINEMATIC)
        self._covariance = np.asarray(state.get('covariance', np.zeros((KINEMATIC, KINEMATIC))),
                                      dtype=float).reshape(KINEMATIC, KINEMATIC)
