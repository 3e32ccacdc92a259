"""After the move, the measured error against the 95 % bound its plan stated (pure policy of the
compensator), and the bound kept honest by every goal that measured it.

**One rule after the move**, for every mode: a measured error beyond the stated bound, widened
by what the camera adds to a measurement (its 95 % error, in quadrature: the bound is of the
true tip, the camera measures it with noise), is the warning, with both figures. It does not
fail a goal: a 95 % bound is missed by one goal in twenty by design, and a goal that needs a
limit gives a tolerance (then the tolerance decides). A goal within its stated bound and
without a tolerance is a success.

**An online bound** (:class:`OnlineBound`): each PREDICTIVE goal's measured error is a new
calibration sample of the model's bound. Its score is the factor on the model's part of the
bound (the site's part and the camera's unchanged) that would just have covered it; the
factor the next plan states is adaptive conformal inference over those scores
(:class:`~flexarm_learning.online_radius.OnlineRadius`, Gibbs & Candès 2021), never below 1
(the held-out calibration), and widened at once by a goal measured beyond ``gross`` times
its bound: a changed arm, not a tail. A new model (training, refresh) starts at 1 again.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_learning.online_radius import OnlineRadius


@dataclass(frozen=True)
class BoundParts:
    """A PREDICTIVE plan's bound in its parts, 95 % each [m, rad]: stated = the model's ×
    the online factor, in quadrature with the site's."""

    model: np.ndarray      # (2,) the model's own (held-out calibration, payload prior)
    site: np.ndarray       # (2,) what no model sees (:class:`~.plan_bound.SiteErrors`)
    factor: float = 1.0    # the online bound's, when planned

    @property
    def stated(self) -> tuple[float, float]:
        position, angle = np.hypot(self.factor * self.model, self.site)
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


def needed_factor(error: tuple[float, float], parts: BoundParts, camera: np.ndarray) -> float:
    """The least factor on the model's part that would have covered ``error`` [m, rad] (with
    the site's part and the camera's): the goal's score."""
    rest = np.hypot(parts.site, camera)
    excess = np.maximum(np.square(error) - np.square(rest), 0.0)
    return float(np.max(np.sqrt(excess) / np.maximum(parts.model, 1e-12)))


@dataclass(frozen=True)
class OnlineSettings:
    gamma: float = 0.005     # ACI's step of the miss level
    window: int = 100        # latest goals the quantile is taken over
    gross: float = 3.0       # a goal beyond this times its stated factor: the arm changed

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> OnlineSettings:
        s = cls(float(d['gamma']), int(d['window']), float(d['gross']))
        if not (0 < s.gamma < 1 and s.window >= 1 and s.gross > 1):
            raise ValueError(f'online_bound: 0 < gamma < 1, window >= 1, gross > 1; got {s}')
        return s


class OnlineBound:
    """The online factor on one model's bound, from the goals measured against it."""

    def __init__(self, settings: OnlineSettings) -> None:
        self.settings = settings
        self.reset('')

    def reset(self, version: str) -> None:
        """A new model: its own calibration again, nothing measured against it."""
        s = self.settings
        self.version = version
        self._radius = OnlineRadius(gamma=s.gamma, window=s.window, floor=1.0, gross=s.gross)
        self.goals = self.misses = 0
        self.last = ''

    @property
    def factor(self) -> float:
        return self._radius.factor

    @property
    def broken(self) -> bool:
        """The measured goals left the model's bound by far: plans state the widest."""
        return self._radius.broken

    def account(self, error: tuple[float, float], parts: BoundParts,
                camera: np.ndarray) -> bool:
        """One goal's measured ``error`` [m, rad] against the bound ``parts`` it was planned
        with; whether that bound covered it."""
        covered = not beyond_bound(error, parts.stated, camera)
        self._radius.update(needed_factor(error, parts, camera), 1.0)
        self.goals += 1
        if not covered:
            self.misses += 1
            self.last = (f'the last miss measured {error[0] * 1e3:.3f} mm against a stated '
                         f'{parts.stated[0] * 1e3:.3f} mm')
        return covered

    def summary(self) -> str:
        """For logs, results and the model health: the factor plans state now and why ('' at
        the calibration's own)."""
        if self.factor <= 1.0:
            return ''
        return (f'plans of model {self.version} state {self.factor:.1f} times its calibrated '
                f'95 % bound: {self.misses} of {self.goals} measured goals were beyond the '
                f'bound stated for them ({self.last})'
                + ('; the model no longer knows its error here: refresh it (`flexarm '
                   'refresh`) or collect and train anew' if self.broken else ''))
