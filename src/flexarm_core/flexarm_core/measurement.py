"""Averaging of several tip-pose frames into one measurement (pure)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Measurement:
    """An averaged tip pose [m, m, rad] with the worst quality figures of its frames."""

    pose: np.ndarray      # (3,) x, y, phi
    spread: np.ndarray    # (3,) max |frame - mean| per component
    frames: int
    holes_used: int
    residual: float       # [m]


def average_frames(poses: np.ndarray, holes_used: int, residual: float) -> Measurement:
    """Mean of (N, 3) poses; phi is averaged on the circle, so ±pi frames do not cancel."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    if len(poses) == 0:
        raise ValueError('no frames to average')
    phi = float(np.arctan2(np.sin(poses[:, 2]).mean(), np.cos(poses[:, 2]).mean()))
    mean = np.array([poses[:, 0].mean(), poses[:, 1].mean(), phi])
    deviation = poses - mean
    deviation[:, 2] = np.angle(np.exp(1j * deviation[:, 2]))
    return Measurement(pose=mean, spread=np.abs(deviation).max(axis=0), frames=len(poses),
                       holes_used=int(holes_used), residual=float(residual))
