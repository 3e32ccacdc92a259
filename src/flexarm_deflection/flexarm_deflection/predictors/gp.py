"""Gaussian-process predictor, one GP per output, with predictive std.

Kernel (``kernel``): constant × (RBF, Matérn ν = 5/2 or 3/2, or RBF + a smaller Matérn 3/2
part) with one length scale per input (ARD) + white noise, on normalised inputs and outputs;
hyperparameters by maximum marginal likelihood with ``restarts`` random restarts (seeded; 4,
and 1 in the cross-validation fits: the RBF + Matérn sum has local optima, and on region B
seed 0 four restarts took the 95th-percentile miss from 0.22 to 0.04 mm).
The kernel's form is not a hyperparameter of the likelihood: training chooses it by
cross-validation (``cv_choices``). The rougher kernels suit a deflection with a sharp
feature — the backlash of joint4 flips where link 4 hangs vertical, inside region B — that
the RBF's infinite smoothness would spread over the whole region; measured on region B (5
training seeds, 200 targets each), the RBF + Matérn sum cut the 95th-percentile miss from
0.12-0.16 mm to 0.03-0.04 mm on three seeds of five. The model file stores the normalised
training set and the fitted hyperparameters (log-θ per output, in scikit-learn's order).

The regression itself is the learning core's (:mod:`flexarm_learning.ard_gp`, scikit-learn's
arithmetic in numpy), shared with the offline study's ``gp`` kind.

Payload: with ``payload_input`` and samples at several payloads, the payload's length scale is
at least ``payload_length_scale`` (in the normalised input: the trained payloads' standard
deviation). The deflection is near linear in the payload (gravity moments grow linearly with
it), and samples at two payloads cannot tell the likelihood so: left free, the length scale
fell to 0.1 on region A (0 and 5 kg, 10 samples each), a 7 mm miss and a 10 mm std at 2.5 kg;
bounded at 2, the miss at 2.5 kg stays within that at the trained payloads.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from flexarm_deflection.predictors.base import Predictor
from flexarm_learning.ard_gp import KERNELS, ArdGp, hyperparameters


class GpPredictor(Predictor):
    """Independent GP regression of dx, dy, dφ; :meth:`deflection_std` gives their std."""

    kind: ClassVar[str] = 'gp'
    defaults: ClassVar[dict[str, Any]] = {
        'length_scale_bounds': [1e-2, 1e3], 'noise_level': 1e-4, 'noise_bounds': [1e-6, 1e-1],
        'restarts': 4, 'seed': 0, 'payload_input': False, 'kernel': 'rbf',
        'payload_length_scale': 2.0}
    cv_choices: ClassVar[dict[str, list[Any]]] = {'kernel': list(KERNELS)}
    cv_overrides: ClassVar[dict[str, Any]] = {'restarts': 1}

    def _check_settings(self) -> None:
        s = self.settings
        for name in ('length_scale_bounds', 'noise_bounds'):
            low_high = s[name]
            if len(low_high) != 2 or not 0 < low_high[0] < low_high[1]:
                raise ValueError(f'gp {name!r} must be [low, high] with 0 < low < high, '
                                 f'got {low_high}')
        if not s['noise_bounds'][0] <= s['noise_level'] <= s['noise_bounds'][1]:
            raise ValueError("gp 'noise_level' must lie within 'noise_bounds'")
        if s['restarts'] < 0:
            raise ValueError("gp 'restarts' must be >= 0")
        if s['payload_length_scale'] <= 0:
            raise ValueError("gp 'payload_length_scale' must be > 0")
        if s['kernel'] not in KERNELS:
            raise ValueError(f"gp 'kernel' must be one of {sorted(KERNELS)}, "
                             f"got {s['kernel']!r}")

    def _hyperparameters(self, inputs: int) -> tuple[np.ndarray, np.ndarray]:
        """Initial log-hyperparameters (p,) and their bounds (p, 2)."""
        s = self.settings
        bounds = np.tile(s['length_scale_bounds'], (inputs, 1))
        if self._payload_varies:
            bounds[-1, 0] = min(s['payload_length_scale'], bounds[-1, 1])
        return hyperparameters(s['kernel'], bounds, s['noise_level'], s['noise_bounds'])

    _payload_varies = False     # the last normalised input is a payload that varied in training

    def fit(self, joints: np.ndarray, deflections: np.ndarray,
            payload: np.ndarray | None = None) -> GpPredictor:
        self._payload_varies = bool(self.settings['payload_input'] and payload is not None
                                    and np.ptp(np.asarray(payload, dtype=float)) > 0)
        return super().fit(joints, deflections, payload)

    def _fit_normalised(self, x: np.ndarray, y: np.ndarray) -> None:
        theta0, bounds = self._hyperparameters(x.shape[1])
        self._gp = ArdGp(self.settings['kernel']).fit(x, y, theta0, bounds,
                                                      self.settings['restarts'],
                                                      self.settings['seed'])

    def _predict_normalised(self, x: np.ndarray) -> np.ndarray:
        return self._gp.mean(x)

    def deflection_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                       ) -> np.ndarray:
        """The posterior's standard deviation [m, m, rad], shaped like :meth:`predict`."""
        x, single = self._inputs(joints, payload)
        normalisation = self._require_fitted()
        std = np.sqrt(self._gp.variance(normalisation.inputs(x))) * normalisation.output_std
        return std[0] if single else std

    def position_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                     ) -> np.ndarray | float:
        std = np.asarray(self.deflection_std(joints, payload))
        position = np.hypot(std[..., 0], std[..., 1])
        return float(position) if position.ndim == 0 else position

    def _state(self) -> dict[str, np.ndarray]:
        return {'x': self._gp.x, 'y': self._gp.y, 'theta': self._gp.theta}

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        self._gp = ArdGp(self.settings['kernel']).condition(
            *(np.asarray(state[key], dtype=float) for key in ('x', 'y', 'theta')))
