"""After the move, the measured error against the 95 % bound its plan stated (pure policy of the
compensator), and the bound kept honest by every goal that measured it.

**One rule after the move**, for every mode: a measured error beyond the stated bound, widened
by what the camera adds to a measurement (its 95 % error, in quadrature: the bound is of the
true tip, the camera measures it with noise), is the warning, with both figures. It does not
fail a goal: a 95 % bound is missed by one goal in twenty by design, and a goal that needs a
limit gives a tolerance (then the tolerance decides). A goal within its stated bound and
without a tolerance is a success.

**An online bound** (:class:`OnlineBound`): each PREDICTIVE goal's measured error is a new
calibration sample of the model's bound. Its scores, position and angle apart, are the factors
on the model's part of the bound (the site's part and the camera's unchanged) that would just
have covered it; the factors the next plan states are adaptive conformal inference over them
(:class:`~flexarm_learning.online_radius.OnlineRadius`, Gibbs & Candès 2021), never below 1
(the held-out calibration).

A goal measured beyond ``gross`` times its bound is no 5 % tail but a changed arm (a load nobody
declared misses by 10-100 times). The model's bound then no longer says how far it misses: an
undeclared load moves the tip by about as much everywhere, whatever the model's bound there,
so a factor on that bound under-covers where it is small. From that goal on, until a new model
comes, every plan states at least ``BEYOND`` times the largest error measured since
(:attr:`Inflation.floor`), and the model health reports it stale. A new model (training,
refresh) starts at factor 1 again.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_learning.online_radius import OnlineRadius

BEYOND = 2.0      # a changed arm: plans state at least this times the largest error since


@dataclass(frozen=True)
class Inflation:
    """What the online bound does to a plan's bound, position and angle."""

    factor: np.ndarray = dataclasses.field(default_factory=lambda: np.ones(2))  # on the model's
    floor: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2))  # [m, rad]


AS_CALIBRATED = Inflation()     # nothing measured against the model yet


@dataclass(frozen=True)
class BoundParts:
    """A PREDICTIVE plan's bound in its parts, 95 % each [m, rad]: stated = the model's ×
    the online factor, in quadrature with the site's, at least the online floor."""

    model: np.ndarray      # (2,) the model's own (held-out calibration, payload prior)
    site: np.ndarray       # (2,) what no model sees (:class:`~.plan_bound.SiteErrors`)
    inflation: Inflation = AS_CALIBRATED

    @property
    def stated(self) -> tuple[float, float]:
        position, angle = np.maximum(np.hypot(self.inflation.factor * self.model, self.site),
                                     self.inflation.floor)
        return float(position), float(angle)


def beyond_bound(error: tuple[float, float], stated: tuple[float, float],
                 camera: np.ndarray) -> str:
    """The warning of a measured ``error`` [m, rad] beyond the ``stated`` bound widened by the
    ``camera``'s 95 % error (module docstring); '' within it."""
    limit = np.hypot(stated, camera)
    if error[0] <= limit[0] and error[1] <= limit[1]:
        return ''
    return (f'warning: measured error {error[0] * 1e3:.3f} mm / {math.degrees(error[1]):.4f} '
            f'deg is beyond the plan\'s 95 % bound {stated[0] * 1e3:.3f} mm / '
            f'{math.degrees(stated[1]):.4f} deg (with the camera\'s '
            f'{camera[0] * 1e3:.3f} mm / {math.degrees(camera[1]):.4f} deg)')


def needed_factor(error: tuple[float, float], parts: BoundParts, camera: np.ndarray,
                  ) -> np.ndarray:
    """(2,): the least factors on the model's part, position and angle, that would have
    covered ``error`` [m, rad] (with the site's part and the camera's): the goal's scores."""
    rest = np.hypot(parts.site, camera)
    excess = np.maximum(np.square(error) - np.square(rest), 0.0)
    return np.sqrt(excess) / np.maximum(parts.model, 1e-12)


@dataclass(frozen=True)
class OnlineSettings:
    """config/compensator.yaml ``online_bound``."""

    gamma: float             # ACI's step of the miss level
    window: int              # latest goals the quantile is taken over
    gross: float             # a goal beyond this times its stated factor: the arm changed

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> OnlineSettings:
        s = cls(float(d['gamma']), int(d['window']), float(d['gross']))
        if not (0 < s.gamma < 1 and s.window >= 1 and s.gross > 1):
            raise ValueError(f'online_bound: 0 < gamma < 1, window >= 1, gross > 1; got {s}')
        return s


class OnlineBound:
    """The online factors on one model's bound, position and angle, from the goals measured
    against it."""

    def __init__(self, settings: OnlineSettings) -> None:
        self.settings = settings
        self.reset('')

    def reset(self, version: str) -> None:
        """A new model: its own calibration again, nothing measured against it."""
        s = self.settings
        self.version = version
        self._radii = [OnlineRadius(gamma=s.gamma, window=s.window, floor=1.0)
                       for _ in range(2)]
        self.goals = self.misses = 0
        self.last = ''
        self._changed = np.zeros(2, bool)      # since a gross miss, position and angle
        self._largest = np.zeros(2)            # [m, rad] measured since

    @property
    def inflation(self) -> Inflation:
        """What the next plan states (module docstring)."""
        return Inflation(np.array([radius.factor for radius in self._radii]),
                         np.where(self._changed, BEYOND * self._largest, 0.0))

    @property
    def broken(self) -> bool:
        """A goal left the model's bound by far: the arm changed since the model learned it."""
        return bool(self._changed.any())

    def account(self, error: tuple[float, float], parts: BoundParts,
                camera: np.ndarray) -> bool:
        """One goal's measured ``error`` [m, rad] against the bound ``parts`` it was planned
        with; whether that bound covered it."""
        covered = not beyond_bound(error, parts.stated, camera)
        scores = needed_factor(error, parts, camera)
        self._changed |= scores > self.settings.gross * parts.inflation.factor
        self._largest = np.where(self._changed, np.maximum(self._largest, error), 0.0)
        for radius, score in zip(self._radii, scores):
            radius.update(float(score), 1.0)
        self.goals += 1
        if not covered:
            self.misses += 1
            self.last = (f'the last miss measured {error[0] * 1e3:.3f} mm against a stated '
                         f'{parts.stated[0] * 1e3:.3f} mm')
        return covered

    def summary(self) -> str:
        """For logs, results and the model health: the factor plans state now and why ('' at
        the calibration's own)."""
        inflation = self.inflation
        position, angle = inflation.factor
        if max(position, angle) <= 1.0 and not self.broken:
            return ''
        return (f'plans of model {self.version} state {position:.1f} (position) and '
                f'{angle:.1f} (angle) times its calibrated 95 % bound: {self.misses} of '
                f'{self.goals} measured goals were beyond the bound stated for them '
                f'({self.last})'
                + (f'; the arm changed since the model learned it: plans state at least '
                   f'{inflation.floor[0] * 1e3:.3f} mm / {math.degrees(inflation.floor[1]):.4f}'
                   ' deg (twice the largest error since); refresh the model (`flexarm '
                   'refresh`) or collect and train anew' if self.broken else ''))
