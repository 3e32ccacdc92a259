"""Error sources of the real arm (config/sim.yaml ``error_sources.*``).

* Repeatability: the servos stop each joint a random N(0, sigma) off its target, drawn anew
  for every joint whose target a command changes. The encoders report the commanded motion;
  the plant sees the position plus the error, which grows from its old to its new value in
  proportion to the joint's progress along the move (no jump of the static pose).
* Hysteresis: friction holds each compliant element (J1, the No.2 guide, J3, J4) up to
  ``fraction`` x its backlash behind its joint's motion, a play operator: J1, J3 and J4 take
  their band up by turning through it, the guide's tilt over ``guide_take_up`` of joint-2
  travel. Opposite approaches of one pose differ by 2 x fraction x backlash; the arm starts
  mid-band.
* Thermal drift: the arm's temperature rises by ``rise`` K along a ramp or a first-order
  approach in sim time; every length grows by ``expansion`` per kelvin.

The camera's errors are in :mod:`flexarm_sim.true_camera`, run-time payload changes in the
sim node. Pure numpy, no rclpy; the draws come from a generator seeded by ``seed``.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

PROFILES = ('ramp', 'first_order')


def active(d: Mapping[str, Any], source: str) -> bool:
    """Whether ``source`` of the ``error_sources`` tree acts: the master and its own switch."""
    return bool(d['enabled']) and bool(d[source]['enabled'])


def seeded(d: Mapping[str, Any], stream: int) -> np.random.Generator:
    """Generator number ``stream`` of the ``error_sources`` seed (independent streams)."""
    return np.random.default_rng([int(d['seed']), stream])


@dataclass(frozen=True)
class Thermal:
    """Temperature rise of the arm over sim time, and the strain it causes."""

    expansion: float      # [1/K]
    rise: float           # [K] final rise over the start temperature
    duration: float       # [s] ramp: time to the full rise; first_order: time constant
    profile: str          # one of PROFILES

    def temperature(self, t: float) -> float:
        """Rise [K] over the start temperature ``t`` seconds of sim time after the start."""
        if self.profile == 'ramp':
            return self.rise * min(t / self.duration, 1.0)
        return self.rise * -math.expm1(-t / self.duration)

    def strain(self, t: float) -> float:
        """Relative growth of every length at sim time ``t`` [s]."""
        return self.expansion * self.temperature(t)


@dataclass(frozen=True)
class Move:
    """A joint command as the servos execute it, with the joint error it ends with."""

    target: np.ndarray    # (4,) commanded positions [rad, m, rad, rad]
    start: np.ndarray     # (4,) positions when it was accepted
    before: np.ndarray    # (4,) joint error at the start
    after: np.ndarray     # (4,) joint error on arrival

    def error(self, q: np.ndarray) -> np.ndarray:
        """Joint error (4,) at positions ``q`` along the move."""
        travel = self.target - self.start
        progress = np.divide(q - self.start, travel, out=np.ones(4), where=travel != 0)
        return self.before + (self.after - self.before) * np.clip(progress, 0.0, 1.0)


class ArmErrors:
    """Repeatability, hysteresis and thermal drift of the arm (zero where switched off)."""

    def __init__(self, sigma: np.ndarray, band: np.ndarray, take_up: np.ndarray,
                 thermal: Thermal | None, rng: np.random.Generator) -> None:
        self.sigma = np.asarray(sigma, dtype=float)       # (4,) [rad, m, rad, rad]
        self.band = np.asarray(band, dtype=float)         # (4,) [rad] half width of the play
        self.take_up = np.asarray(take_up, dtype=float)   # (4,) joint travel per band
        self.thermal = thermal
        self._rng = rng

    @classmethod
    def none(cls) -> ArmErrors:
        """The ideal arm."""
        zero = np.zeros(4)
        return cls(zero, zero, zero, None, np.random.default_rng(0))

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], backlash: np.ndarray) -> ArmErrors:
        """From config/sim.yaml ``error_sources.*`` and the plant's backlash (4,) [rad]."""
        sigma, band, take_up, thermal = np.zeros(4), np.zeros(4), np.zeros(4), None
        if active(d, 'repeatability'):
            sigma = np.asarray(d['repeatability']['sigma'], dtype=float)
            if sigma.shape != (4,) or np.any(sigma < 0):
                raise ValueError('error_sources.repeatability.sigma: 4 values >= 0')
        if active(d, 'hysteresis'):
            h = d['hysteresis']
            fraction, guide = float(h['fraction']), float(h['guide_take_up'])
            if not 0 <= fraction <= 0.5 or guide <= 0:
                raise ValueError('error_sources.hysteresis: 0 <= fraction <= 0.5 (inside the '
                                 'backlash) and guide_take_up > 0')
            band = fraction * np.asarray(backlash, dtype=float)
            take_up = np.array([2 * band[0], guide, 2 * band[2], 2 * band[3]])
        if active(d, 'thermal'):
            t = d['thermal']
            thermal = Thermal(float(t['expansion']), float(t['rise']), float(t['duration']),
                              str(t['profile']))
            if thermal.profile not in PROFILES or thermal.duration <= 0:
                raise ValueError(f'error_sources.thermal: profile one of {PROFILES} and '
                                 'duration > 0')
        return cls(sigma, band, take_up, thermal, seeded(d, 0))

    def start(self, q: np.ndarray) -> Move:
        """The arm at rest at ``q``: no joint error yet."""
        return Move(q.copy(), q.copy(), np.zeros(4), np.zeros(4))

    def plan(self, move: Move, q: np.ndarray, target: np.ndarray) -> Move:
        """The move to ``target`` accepted at positions ``q`` during ``move`` (the same move
        if ``target`` is its target: a repeated command is no new move)."""
        if np.array_equal(target, move.target):
            return move
        now = move.error(q)
        moving = (target != move.target) & (target != q)
        after = np.where(moving, self._rng.normal(0.0, 1.0, 4) * self.sigma, now)
        return Move(target.copy(), q.copy(), now, after)

    def slip(self, play: np.ndarray, motion: np.ndarray) -> np.ndarray:
        """Play state (4,) in -1..1 (-1: lagging behind a positive motion) after the joints
        moved by ``motion`` (4,); the friction offsets are ``band * play`` [rad]."""
        steps = np.divide(2 * motion, self.take_up, out=np.zeros(4), where=self.take_up > 0)
        return np.clip(play - steps, -1.0, 1.0)

    def strain(self, t: float) -> float:
        """Thermal strain at sim time ``t`` [s] (0 with the source off)."""
        return 0.0 if self.thermal is None else self.thermal.strain(t)
