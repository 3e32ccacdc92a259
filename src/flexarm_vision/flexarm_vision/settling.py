"""Is the arm at rest? Decided from joint states and from the image itself (pure).

A measurement counts as *settled* when
1. every joint has been still (|velocity| below a tolerance) for at least ``still_time``
   seconds — the commanded motion is over — and
2. the last ``window`` valid pose estimates, including this one, agree within ``stability``
   (position, m) and ``angle_stability`` (rad) — the tip vibration has decayed below what the
   measurement is used for.
Joint states alone cannot see the vibration of a flexible arm (the joints stand still while the
tip rings at 3.6-12 Hz, paper Table 6); the image alone cannot tell a slow move from a drift.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class SettleSettings:
    still_time: float           # [s]
    velocity_tolerance: float   # [rad/s or m/s]
    window: int                 # consecutive estimates compared
    stability: float            # [m]
    angle_stability: float      # [rad]

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SettleSettings:
        settings = cls(still_time=float(d['still_time']),
                       velocity_tolerance=float(d['velocity_tolerance']),
                       window=int(d['window']), stability=float(d['stability']),
                       angle_stability=float(d['angle_stability']))
        if settings.window < 2 or min(settings.still_time, settings.velocity_tolerance,
                                      settings.stability, settings.angle_stability) <= 0:
            raise ValueError(f'invalid settle settings {settings}')
        return settings


class SettleDetector:
    """Tracks joint stillness and estimate stability over time."""

    def __init__(self, settings: SettleSettings) -> None:
        self.settings = settings
        self._still_since: float | None = None
        self._estimates: deque[tuple[float, np.ndarray]] = deque(maxlen=settings.window)

    def update_joints(self, t: float, velocities: np.ndarray) -> None:
        moving = bool(np.any(np.abs(velocities) > self.settings.velocity_tolerance))
        if moving:
            self._still_since = None
            self._estimates.clear()
        elif self._still_since is None:
            self._still_since = t

    def update_estimate(self, t: float, pose: np.ndarray | None) -> str | None:
        """Record the estimate at ``t`` (None if invalid); None if settled, else the reason."""
        if pose is None:
            self._estimates.clear()
            return 'invalid measurement'
        self._estimates.append((t, np.asarray(pose, dtype=float)))
        if self._still_since is None:
            return 'joints moving (or no joint states)'
        if t - self._still_since < self.settings.still_time:
            return f'joints still for {t - self._still_since:.2f} s < {self.settings.still_time} s'
        recent = [p for ts, p in self._estimates if ts >= self._still_since]
        if len(recent) < self.settings.window:
            return f'{len(recent)}/{self.settings.window} stable frames'
        poses = np.array(recent)
        spread_xy = float(np.max(np.ptp(poses[:, :2], axis=0)))
        spread_phi = float(np.ptp(np.unwrap(poses[:, 2])))
        if spread_xy > self.settings.stability or spread_phi > self.settings.angle_stability:
            return (f'tip vibrating: spread {spread_xy * 1e3:.3f} mm, '
                    f'{np.degrees(spread_phi):.4f} deg')
        return None
