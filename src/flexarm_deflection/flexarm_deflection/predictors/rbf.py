"""Radial basis function predictor: ``scipy.interpolate.RBFInterpolator`` on normalised inputs.

The model file stores the normalised training set; the interpolator is rebuilt from it on
load (a deterministic linear solve, so predictions are the same as before saving).

``smoothing`` defaults to 1e-3 (normalised outputs), not 0: exact interpolation of a pose
measured twice (joints within the arrival tolerance, different camera noise) fits the noise
with a steep spike and the held-out error grows tenfold; 1e-3 removes that and costs nothing
measurable on poses measured once.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from flexarm_deflection.predictors.base import Predictor

# Kernels of RBFInterpolator with the least polynomial degree that keeps the fit well posed.
KERNEL_MIN_DEGREE = {
    'linear': 0, 'thin_plate_spline': 1, 'cubic': 1, 'quintic': 2, 'multiquadric': 0,
    'inverse_multiquadric': -1, 'inverse_quadratic': -1, 'gaussian': -1}


class RbfPredictor(Predictor):
    """RBF interpolation (``smoothing`` > 0 turns it into smoothing regression)."""

    kind: ClassVar[str] = 'rbf'
    defaults: ClassVar[dict[str, Any]] = {
        'kernel': 'thin_plate_spline', 'smoothing': 1e-3, 'epsilon': 1.0, 'degree': 1,
        'payload_input': False}
    cv_choices: ClassVar[dict[str, list[Any]]] = {'smoothing': [1e-4, 1e-3, 1e-2]}

    def _check_settings(self) -> None:
        s = self.settings
        if s['kernel'] not in KERNEL_MIN_DEGREE:
            raise ValueError(f"rbf 'kernel' must be one of {sorted(KERNEL_MIN_DEGREE)}, "
                             f"got {s['kernel']!r}")
        if s['degree'] < KERNEL_MIN_DEGREE[s['kernel']]:
            raise ValueError(f"rbf kernel {s['kernel']!r} needs 'degree' >= "
                             f"{KERNEL_MIN_DEGREE[s['kernel']]}, got {s['degree']}")
        if s['smoothing'] < 0 or s['epsilon'] <= 0:
            raise ValueError("rbf needs 'smoothing' >= 0 and 'epsilon' > 0")

    def _fit_normalised(self, x: np.ndarray, y: np.ndarray) -> None:
        from scipy.interpolate import RBFInterpolator

        self._interpolator = RBFInterpolator(
            x, y, kernel=self.settings['kernel'], smoothing=self.settings['smoothing'],
            epsilon=self.settings['epsilon'], degree=self.settings['degree'])
        self._x, self._y = x, y

    def _predict_normalised(self, x: np.ndarray) -> np.ndarray:
        return self._interpolator(x)

    def _state(self) -> dict[str, np.ndarray]:
        return {'x': self._x, 'y': self._y}

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        self._fit_normalised(np.asarray(state['x'], dtype=float),
                             np.asarray(state['y'], dtype=float))
