"""How fast a predicted deflection changes with the commanded pose: whether the compensator's
fixed point x* = x_d − Δ(IK(x*)) can be solved with a model. Training refuses a model whose
slope is too steep at its training poses (:mod:`~flexarm_deflection.selection`); the
compensator's Newton solver (:mod:`~flexarm_control.execution.compensator`) moves the same
joints with the same finite-difference step.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from flexarm_core.kinematics import ArmGeometry, forward, wrap_angle

FREE = [0, 2, 3]          # joints the compensator's Newton solver moves (θ2 is kept)
JACOBIAN_STEP = 1e-6      # [rad] finite-difference step of the Jacobian

Predict = Callable[[np.ndarray], np.ndarray]


def deflection_slope(geometry: ArmGeometry, predict: Predict, joints: np.ndarray
                     ) -> np.ndarray:
    """How fast the predicted deflection changes with the commanded pose at joints (M, 4):
    the spectral norm of dΔ/dx* (θ2 kept, angles weighted by l4 as tip-length metres), (M,).
    Below 1 the paper's iteration contracts; near or above it the deflection can cancel the
    motion and the compensated target is ill-posed."""
    q = np.atleast_2d(np.asarray(joints, dtype=float))
    weight = np.array([1.0, 1.0, geometry.link4])
    probes = q[:, None, :] + JACOBIAN_STEP * np.eye(4)[FREE][None]    # (M, 3, 4)
    base_pose, base_deflection = forward(geometry, q), np.asarray(predict(q), dtype=float)
    moved = probes.reshape(-1, 4)
    d_pose = forward(geometry, moved).reshape(len(q), len(FREE), 3) - base_pose[:, None]
    d_pose[..., 2] = wrap_angle(d_pose[..., 2])
    d_defl = (np.asarray(predict(moved), dtype=float).reshape(len(q), len(FREE), 3)
              - base_deflection[:, None])
    # Rows: joints; J_x = d_pose.T, J_d = d_defl.T per sample; dΔ/dx* = J_d J_x^-1.
    jx = np.swapaxes(d_pose * weight, 1, 2)
    jd = np.swapaxes(d_defl * weight, 1, 2)
    return np.linalg.norm(jd @ np.linalg.inv(jx), ord=2, axis=(1, 2))
