"""A move's joint reference: the time-optimal synchronized profile, convolved with an input
shaper (:mod:`flexarm_motion.shaping`), sampled for a joint trajectory.

Profile (:func:`plan_profile`): every joint follows one path parameter s(t) from 0 to 1,
q(t) = q0 + (q1 − q0) s(t), so all joints start and end together and the arm moves along the
straight line in joint space. s is a trapezoid in speed (a triangle where the move is too
short to reach speed) whose peak rate ṡ and acceleration s̈ are the largest the joints allow:
s̈ = min_i a_i/|Δq_i|, ṡ = min(min_i v_i/|Δq_i|, √s̈); the fastest such profile, of duration
1/ṡ + ṡ/s̈. The limits are config/arm.yaml's ``arm.velocity`` and ``arm.acceleration``.

Shaping (:func:`shape_move`): s is convolved with the shaper's impulses, s_shaped(t) =
Σ A_j s(t − t_j), evaluated exactly at each sample (no discrete convolution error). Its speed
and acceleration are averages of the unshaped ones with the positive weights A_j summing to 1:
never beyond the limits. The move lasts the profile's duration plus the shaper's.

:class:`MovePlanner` plans a node's moves so: the limits and the nominal tip mode from the
robot description (config/arm.yaml), the shaper from config/motion.yaml ``motion.shaping``
(``auto``: the shortest that keeps the ringing within 5 % over ±``frequency_uncertainty`` of
the tabulated frequency, :func:`~flexarm_motion.shaping.choose_shaper`).
Pure numpy.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_core.natural_frequency import NaturalFrequency
from flexarm_motion.shaping import Shaper, choose_shaper


@dataclass(frozen=True)
class JointProfile:
    """q(t) = start + (end − start)·s(t), s a trapezoid: ramp ``ramp`` s at ``acceleration``
    [1/s²] up to ``rate`` [1/s], cruise, ramp down; ``duration`` [s] in all."""

    start: np.ndarray       # (n,) joint positions [rad, m, ...]
    end: np.ndarray         # (n,)
    rate: float             # [1/s] peak ṡ (0: no motion)
    acceleration: float     # [1/s²] |s̈| on the ramps
    duration: float         # [s]

    @property
    def ramp(self) -> float:
        """[s] of each acceleration ramp."""
        return self.rate / self.acceleration if self.rate else 0.0

    def path(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """s, ṡ, s̈ at times ``t`` [s] (s = 0 before the start, 1 after the end)."""
        t = np.asarray(t, dtype=float)
        if not self.rate:
            return (t >= 0).astype(float), np.zeros_like(t), np.zeros_like(t)
        a, ramp, total = self.acceleration, self.ramp, self.duration
        up = np.clip(t, 0.0, ramp)
        cruise = np.clip(t - ramp, 0.0, max(total - 2 * ramp, 0.0))
        down = np.clip(t - (total - ramp), 0.0, ramp)
        s = a * up ** 2 / 2 + self.rate * cruise + self.rate * down - a * down ** 2 / 2
        sd = a * (up - down)
        sdd = np.select([(t >= 0) & (t < ramp), (t >= total - ramp) & (t < total)], [a, -a], 0.0)
        return s, sd, sdd


@dataclass(frozen=True)
class ShapedMove:
    """A shaped joint reference sampled for a joint trajectory (rows: samples)."""

    times: np.ndarray           # (k,) [s] from the move's start; the last is its end
    positions: np.ndarray       # (k, n) [rad, m, ...]
    velocities: np.ndarray      # (k, n) [rad/s, m/s, ...]
    accelerations: np.ndarray   # (k, n) [rad/s², m/s², ...]
    shaper: Shaper

    @property
    def duration(self) -> float:
        """[s] the profile's plus the shaper's."""
        return float(self.times[-1])


def plan_profile(start: np.ndarray, end: np.ndarray, velocity: np.ndarray,
                 acceleration: np.ndarray) -> JointProfile:
    """The fastest synchronized profile from ``start`` to ``end`` within the joints' speed and
    acceleration limits (positive, one per joint)."""
    q0, q1 = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    vmax, amax = np.asarray(velocity, dtype=float), np.asarray(acceleration, dtype=float)
    if not (q0.shape == q1.shape == vmax.shape == amax.shape and q0.ndim == 1):
        raise ValueError('start, end and the limits need one value per joint')
    if not (np.all(np.isfinite(q0)) and np.all(np.isfinite(q1))
            and np.all(vmax > 0) and np.all(amax > 0)):
        raise ValueError('finite positions and positive limits needed')
    distance = np.abs(q1 - q0)
    moving = distance > 0
    if not moving.any():
        return JointProfile(q0, q1, 0.0, 0.0, 0.0)
    acc = float(np.min(amax[moving] / distance[moving]))
    rate = min(float(np.min(vmax[moving] / distance[moving])), math.sqrt(acc))
    return JointProfile(q0, q1, rate, acc, 1.0 / rate + rate / acc)


def shape_move(profile: JointProfile, shaper: Shaper, period: float) -> ShapedMove:
    """``profile`` convolved with ``shaper``, sampled every ``period`` [s] from 0 and at its
    end (the last interval may be shorter)."""
    if not period > 0:
        raise ValueError(f'sample period must be positive, got {period}')
    total = profile.duration + shaper.duration
    times = np.arange(0.0, total, period)
    times = np.append(times[times < total - 1e-9 * period], total)
    lag = times[:, None] - shaper.times[None, :]
    s, sd, sdd = (channel @ shaper.amplitudes for channel in profile.path(lag))
    delta = profile.end - profile.start
    positions = profile.start + np.outer(s, delta)
    positions[-1] = profile.end          # exactly the target, not within rounding of it
    return ShapedMove(times, positions, np.outer(sd, delta), np.outer(sdd, delta), shaper)


@dataclass(frozen=True)
class MovePlanner:
    """Plans a move's shaped joint reference (pure): the profile within ``velocity`` and
    ``acceleration``, the ``shaping`` shaper at the tip mode of ``payload`` [kg] and the target's
    No.2 arm length, sampled every ``period`` s."""

    velocity: np.ndarray
    acceleration: np.ndarray
    period: float
    shaping: str
    mode: NaturalFrequency
    damping_ratio: float

    @classmethod
    def from_dicts(cls, motion: Mapping[str, Any], arm: Mapping[str, Any]) -> MovePlanner:
        tip = arm['tip_mode']
        damping, kind = float(tip['damping_ratio']), str(motion['shaping'])
        if kind == 'auto':      # the choice depends on the frequency's ratio alone
            kind = choose_shaper(1.0, damping, float(motion['frequency_uncertainty'])).kind
        planner = cls(np.asarray(arm['velocity'], dtype=float),
                      np.asarray(arm['acceleration'], dtype=float),
                      float(motion['trajectory_period']), kind,
                      NaturalFrequency.from_dict(tip['natural_frequency']), damping)
        Shaper.design(planner.shaping, 1.0, planner.damping_ratio)     # ValueError if unknown
        if not planner.period > 0:
            raise ValueError(f'motion.trajectory_period must be > 0, got {planner.period}')
        return planner

    def shaper(self, payload: float, target: np.ndarray) -> Shaper:
        return Shaper.design(self.shaping, self.mode(payload, float(target[1])),
                             self.damping_ratio)

    def plan(self, start: np.ndarray, target: np.ndarray, payload: float) -> ShapedMove:
        """The move from ``start`` to ``target``; at least one point after the start."""
        shaper = self.shaper(payload, target)
        profile = plan_profile(start, target, self.velocity, self.acceleration)
        if not profile.duration:                # already there: one point, to hold it
            return self._still(target, self.period, shaper)
        return shape_move(profile, shaper, self.period)

    def stop(self, here: np.ndarray) -> ShapedMove:
        """Back to ``here`` at rest, from wherever the joints are and however fast they go:
        in the time the cubic from full speed back to its start takes within the acceleration
        limits (it starts braking at 4 v / T)."""
        stop_time = float(4 * np.max(self.velocity / self.acceleration))
        return self._still(here, stop_time, Shaper.design('off', 1.0, 0.0))

    @staticmethod
    def _still(at: np.ndarray, after: float, shaper: Shaper) -> ShapedMove:
        still = np.array([at, at], dtype=float)
        return ShapedMove(np.array([0.0, after]), still, np.zeros_like(still),
                          np.zeros_like(still), shaper)
