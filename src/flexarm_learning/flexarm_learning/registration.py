"""Rigid registration of measured points to modelled ones: the instrument's frame is not the
arm's base frame, so every calibration tool identifies the instrument-to-base transform first
(here jointly with the model: :mod:`.elastostatic`). Kabsch's solution starts it."""
from __future__ import annotations

import numpy as np


def kabsch(model: np.ndarray, measured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t with ``measured ≈ model @ R.T + t`` (least squares)."""
    a, b = model.mean(axis=0), measured.mean(axis=0)
    u, _, vt = np.linalg.svd((model - a).T @ (measured - b))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rotation = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return rotation, b - rotation @ a


def rotation_vector(omega: np.ndarray) -> np.ndarray:
    """The rotation matrix exp([ω]×) (Rodrigues)."""
    angle = float(np.linalg.norm(omega))
    k = skew(omega)
    if angle < 1e-12:
        return np.eye(3) + k
    return (np.eye(3) + np.sin(angle) / angle * k
            + (1.0 - np.cos(angle)) / angle ** 2 * k @ k)


def skew(v: np.ndarray) -> np.ndarray:
    """[v]×, such that skew(v) @ w = v × w; batched over leading axes."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out
