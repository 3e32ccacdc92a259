"""The 95 % error bound a plan states before anything moves (pure policy of the compensator).

* PREDICTIVE: the model's own bound at the joints to command and the payload carried
  (:meth:`~flexarm_deflection.predictors.Predictor.error_bound`: its raw std scaled on
  held-out samples, with the masses' prior where the samples had one payload), and what no
  model sees (:class:`SiteErrors`): the arm's thermal growth since its samples were taken
  (the held-out samples are of one time; the model health mends a growth that shows), what
  the tool calibration leaves of the camera's own error (the learner learns the camera's pose;
  a camera error the calibration did not remove is in every sample and no held-out sample
  shows it), and the servos' positioning error where /joint_states does not show it, carried
  to the tip through the arm's Jacobian (the 95 % radius of that tip error's own ellipse: the
  joints' errors move the tip mostly across the arm, near one-dimensional, where 1.96 σ holds
  rather than a round error's 2.45 σ per axis). The camera's noise, and the servos' error
  where /joint_states reports the commanded position, are in the held-out residuals already.
  Each at its own 95 % point, summed in quadrature (independent sources).
* CLOSED_LOOP: the goal ends when the measured tip is within its tolerance, so the true tip
  is within the tolerance plus the camera's 95 % error (one measurement's noise and the tool
  residual) — whatever the model.
* RIGID: the model's predicted deflection there (what the rigid plan leaves) plus its
  PREDICTIVE bound; without a model, the rigid model's largest error of the paper's Table 10.

A bound is NaN when it cannot be stated: a model fitted outside the learner's training has no
held-out calibration.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_core.kinematics import ArmGeometry, forward
from flexarm_core.paper import TABLE_10
from flexarm_deflection.error_bound import Z_1D, Z_2D
from flexarm_deflection.predictors.kinematic import KINEMATIC, pose_jacobian

# [m, rad] the rigid model's largest errors over the paper's Table 10 (16 mm, 3.8 deg)
RIGID_ERROR = tuple(max(t.rigid_errors[i] for t in TABLE_10 if t.rigid_errors) * unit
                    for i, unit in ((0, 1e-3), (1, math.pi / 180)))
# Fixed standard normal draws (2, n): the 95 % radius of any 2-D normal error, deterministic
_NORMAL = np.random.default_rng(0).standard_normal((2, 20000))


@dataclass(frozen=True)
class SiteErrors:
    """What no learned model sees, one standard deviation, as a site states it
    (config/compensator.yaml ``error_bound``)."""

    joint_repeatability: np.ndarray       # (4,) [rad, m, rad, rad] that /joint_states hides
    tool_residual: tuple[float, float]    # [m, rad] what the tool calibration leaves
    camera_noise: tuple[float, float]     # [m, rad] of one measured tip pose
    thermal_strain: float = 0.0           # [-] the arm's length change since its samples

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SiteErrors:
        errors = cls(np.asarray(d['joint_repeatability'], dtype=float),
                     tuple(float(v) for v in d['tool_residual']),
                     tuple(float(v) for v in d['camera_noise']), float(d['thermal_strain']))
        if (errors.joint_repeatability.shape != (4,) or len(errors.tool_residual) != 2
                or len(errors.camera_noise) != 2 or min(*errors.joint_repeatability,
                                                        *errors.tool_residual,
                                                        *errors.camera_noise,
                                                        errors.thermal_strain) < 0):
            raise ValueError(f'error_bound: joint_repeatability needs 4 values, tool_residual '
                             f'and camera_noise 2, thermal_strain 1, all >= 0; got {errors}')
        return errors

    def at(self, geometry: ArmGeometry, joints: np.ndarray) -> np.ndarray:
        """95 % [m, rad] of what the servos, the arm's growth and the tool calibration add at
        ``joints`` (the growth is about joint1, along the line to the tip)."""
        links = {'link3': geometry.link3, 'link4': geometry.link4, 'offset': geometry.offset}
        jacobian = pose_jacobian(links, np.asarray(joints, dtype=float)[np.newaxis],
                                 np.zeros(KINEMATIC))[0, :, :4]     # the joint zero offsets'
        covariance = jacobian @ np.diag(self.joint_repeatability ** 2) @ jacobian.T
        servo = (radius_95(covariance[:2, :2]), Z_1D * math.sqrt(covariance[2, 2]))
        growth = Z_1D * self.thermal_strain * float(np.hypot(*forward(geometry, joints)[:2]))
        return np.hypot(np.hypot(servo, (growth, 0.0)), Z_1D * np.asarray(self.tool_residual))

    @property
    def camera(self) -> np.ndarray:
        """95 % [m, rad] of one measured tip pose's error: the camera's noise and what the
        tool calibration left."""
        return np.hypot([Z_2D * self.camera_noise[0], Z_1D * self.camera_noise[1]],
                        Z_1D * np.asarray(self.tool_residual))

    def closed_loop(self, tolerance: tuple[float, float]) -> np.ndarray:
        """95 % [m, rad] of a CLOSED_LOOP goal's true error that ends within ``tolerance``."""
        return np.asarray(tolerance, dtype=float) + self.camera


def radius_95(covariance: np.ndarray) -> float:
    """95 % point of |e| for e ~ N(0, ``covariance`` (2, 2)): 1.96 σ for a one-dimensional
    error, 2.45 σ per axis for a round one."""
    spread = np.sqrt(np.maximum(np.linalg.eigvalsh(covariance), 0.0))
    return float(np.percentile(np.hypot(*(spread[:, None] * _NORMAL)), 95))

