"""A joint trajectory as joint_trajectory_controller executes it (pure core).

Points give positions and velocities at times from the trajectory's start; between two points
the reference is the cubic through their positions and velocities (the controller's spline
without accelerations), and before the first point the cubic from where the reference was, and
how fast it went, when the trajectory came. After the last point it holds the last position.
The simulator follows it in simulated time; a controller side builds it from its planned
moves.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SampledTrajectory:
    """``positions``/``velocities`` (k, n) at ``times`` (k,) [s] from the start, which is at
    ``start`` (n,) moving at ``start_velocity`` (n,)."""

    start: np.ndarray
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    start_velocity: np.ndarray

    @classmethod
    def from_points(cls, start: np.ndarray, times: np.ndarray, positions: np.ndarray,
                    velocities: np.ndarray | None = None) -> SampledTrajectory:
        """ValueError unless the times rise from above 0 and every point has a finite value
        per joint (velocities: none given, all zero)."""
        start = np.asarray(start, dtype=float)
        times = np.asarray(times, dtype=float)
        positions = np.asarray(positions, dtype=float)
        velocities = (np.zeros_like(positions) if velocities is None
                      else np.asarray(velocities, dtype=float))
        n = start.size
        if (times.ndim != 1 or times.size == 0 or positions.shape != (times.size, n)
                or velocities.shape != positions.shape):
            raise ValueError(f'a trajectory needs points of {n} positions (and velocities)')
        if not (times[0] > 0 and np.all(np.diff(times) > 0)):
            raise ValueError('trajectory times must rise from above 0')
        if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(velocities))):
            raise ValueError('trajectory points must be finite')
        return cls(start, times, positions, velocities, np.zeros_like(start))

    def starting(self, position: np.ndarray, velocity: np.ndarray) -> SampledTrajectory:
        """This trajectory from where the reference is, and how fast it goes, as it comes."""
        return dataclasses.replace(self, start=np.asarray(position, dtype=float).copy(),
                                   start_velocity=np.asarray(velocity, dtype=float).copy())

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    @property
    def end(self) -> np.ndarray:
        return self.positions[-1]

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities (n,) of the reference at ``t`` [s] from the start."""
        if t >= self.times[-1]:
            return self.positions[-1].copy(), np.zeros_like(self.positions[-1])
        i = int(np.searchsorted(self.times, t, side='right'))
        if i == 0:
            t0, p0, v0 = 0.0, self.start, self.start_velocity
        else:
            t0, p0, v0 = self.times[i - 1], self.positions[i - 1], self.velocities[i - 1]
        t1, p1, v1 = self.times[i], self.positions[i], self.velocities[i]
        h = t1 - t0
        s = max(t - t0, 0.0) / h
        h00, h10 = 2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s
        h01, h11 = -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2
        q = h00 * p0 + h10 * h * v0 + h01 * p1 + h11 * h * v1
        d00, d10 = (6 * s ** 2 - 6 * s) / h, 3 * s ** 2 - 4 * s + 1
        d01, d11 = (-6 * s ** 2 + 6 * s) / h, 3 * s ** 2 - 2 * s
        return q, d00 * p0 + d10 * v0 + d01 * p1 + d11 * v1
