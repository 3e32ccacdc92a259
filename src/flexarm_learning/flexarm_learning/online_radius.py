"""A 95 % radius that keeps holding while the arm drifts: adaptive conformal inference (Gibbs
& Candès, NeurIPS 2021) on the measured goals.

A split-conformal radius (:mod:`.error_radius`) is calibrated once: when the world moves
(temperature, a load nobody declared, wear) its coverage falls and nothing says so. Here every
measured goal is a new calibration sample. Its score (|error| / ρ) joins a window of the most
recent ``window`` scores (the calibration's to start with), and the miss level α moves by
``gamma`` × (0.05 − miss): after a miss the next radius is a higher quantile of the window,
after a hit a slightly lower one. The long-run miss rate then stays at 5 % whatever the drift
(the paper's guarantee: |mean miss − 0.05| ≤ (max(α₁, 1 − α₁) + γ) / (γ T) over T goals).
α ≤ 0 states no finite radius (the largest score in the window stands in, times
``beyond``): the model no longer knows its error, and says so.
"""
from __future__ import annotations

from collections import deque

import numpy as np

LEVEL = 0.95
GAMMA = 0.005        # Gibbs & Candès' step
WINDOW = 500         # recent scores the quantile is taken over
BEYOND = 2.0         # the radius when α ≤ 0: this times the window's largest score


class OnlineRadius:
    """The factor on a prediction's raw spread ρ that states its 95 % radius, updated from
    each measured error."""

    def __init__(self, scores: np.ndarray, level: float = LEVEL, gamma: float = GAMMA,
                 window: int = WINDOW) -> None:
        self.target = 1.0 - level
        self.alpha, self.gamma = self.target, gamma
        self.scores = deque(np.asarray(scores, float), maxlen=window)

    @property
    def factor(self) -> float:
        """The factor of the next radius: the window's (1 − α) quantile."""
        if self.alpha <= 0.0:
            return BEYOND * max(self.scores)
        return float(np.quantile(np.asarray(self.scores), min(1.0 - self.alpha, 1.0),
                                 method='higher'))

    def update(self, error: float, spread: float) -> bool:
        """Account one measured goal: its error and its prediction's raw spread ρ [m].
        Whether the radius stated before it covered it."""
        covered = error <= self.factor * spread
        self.alpha += self.gamma * (self.target - (0.0 if covered else 1.0))
        self.scores.append(error / spread)
        return covered
