"""A 95 % radius that keeps holding while the arm drifts: adaptive conformal inference (Gibbs
& Candès, NeurIPS 2021) on the measured goals.

A split-conformal radius (:mod:`.error_radius`) is calibrated once: when the world moves
(temperature, a load nobody declared, wear) its coverage falls and nothing says so. Here every
measured goal is a new calibration sample. Its score (|error| / ρ) joins a window of the most
recent ``window`` scores (the calibration's to start with, if there are any), and the miss
level α moves by ``gamma`` × (0.05 − miss): after a miss the next radius is a higher quantile
of the window, after a hit a slightly lower one. The long-run miss rate then stays at 5 %
whatever the drift (the paper's guarantee: |mean miss − 0.05| ≤ (max(α₁, 1 − α₁) + γ) / (γ T)
over T goals). α ≤ 0 states no finite quantile: the model no longer knows its error, says so
(:attr:`OnlineRadius.broken`), and the largest score in the window times ``BEYOND`` stands in.

For a controller that states its bound before each goal, ``floor``: the factor is never below
it. A model whose bound was calibrated on held-out samples states factor 1 until measured goals
show otherwise; a few lucky goals do not make it bolder than its calibration. It may start
with no scores at all (then the floor is the factor).

Below the rank a window can state (fewer than 19 scores at 95 %), the largest score stands in.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable

import numpy as np

LEVEL = 0.95
GAMMA = 0.005        # Gibbs & Candès' step
WINDOW = 500         # recent scores the quantile is taken over
BEYOND = 2.0         # the radius when α ≤ 0: this times the window's largest score


class OnlineRadius:
    """The factor on a prediction's raw spread ρ that states its 95 % radius, updated from
    each measured error."""

    def __init__(self, scores: Iterable[float] = (), level: float = LEVEL,
                 gamma: float = GAMMA, window: int = WINDOW, floor: float = 0.0) -> None:
        self.target = 1.0 - level
        self.alpha, self.gamma, self.floor = self.target, gamma, floor
        self.scores = deque(np.asarray(list(scores), float), maxlen=window)

    @property
    def broken(self) -> bool:
        """Whether the measured goals have left every quantile the window states (α ≤ 0)."""
        return self.alpha <= 0.0

    @property
    def factor(self) -> float:
        """The factor of the next radius: the window's conformal (1 − α) quantile."""
        if not self.scores:              # nothing measured yet: the floor, or no radius
            return self.floor or math.inf
        if self.broken:
            return max(self.floor, BEYOND * max(self.scores))
        ordered = np.sort(np.asarray(self.scores))
        rank = math.ceil((len(ordered) + 1) * (1.0 - self.alpha))
        return max(self.floor, float(ordered[min(rank, len(ordered)) - 1]))

    def update(self, error: float, spread: float) -> bool:
        """Account one measured goal: its error and its prediction's raw spread ρ [m].
        Whether the radius stated before it covered it."""
        score = error / spread
        covered = score <= self.factor
        self.alpha += self.gamma * (self.target - (0.0 if covered else 1.0))
        self.scores.append(score)
        return covered
