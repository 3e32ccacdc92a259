"""Gaussian-process predictor (scikit-learn), one GP per output, with predictive std.

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
training set and the fitted hyperparameters (log-θ per output); the GPs are rebuilt on load
without re-optimising. scikit-learn (~0.5 s to import) is imported when a GP is built, not with
this module: a node that never fits or loads a GP does not pay for it.

Payload: with ``payload_input`` and samples at several payloads, the payload's length scale is
at least ``payload_length_scale`` (in the normalised input: the trained payloads' standard
deviation). The deflection is near linear in the payload (gravity moments grow linearly with
it), and samples at two payloads cannot tell the likelihood so: left free, the length scale
fell to 0.1 on region A (0 and 5 kg, 10 samples each), a 7 mm miss and a 10 mm std at 2.5 kg;
bounded at 2, the miss at 2.5 kg stays within that at the trained payloads.
"""
from __future__ import annotations

import warnings
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from flexarm_control.predictors.base import OUTPUTS, Predictor

if TYPE_CHECKING:
    from sklearn.gaussian_process.kernels import Kernel

KERNELS = ('rbf', 'matern52', 'matern32', 'rbf+matern32')


class GpPredictor(Predictor):
    """Independent GP regression of dx, dy, dφ; :meth:`predict_std` gives their std."""

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

    def _kernel(self, inputs: int) -> Kernel:
        from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Matern, WhiteKernel

        s = self.settings
        bounds = np.tile(s['length_scale_bounds'], (inputs, 1))
        if self._payload_varies:
            bounds[-1, 0] = min(s['payload_length_scale'], bounds[-1, 1])
        scales = np.maximum(1.0, bounds[:, 0])
        smooth = RBF(scales, bounds)
        shape = {'rbf': smooth,
                 'matern52': Matern(scales, bounds, nu=2.5),
                 'matern32': Matern(scales, bounds, nu=1.5),
                 'rbf+matern32': smooth + ConstantKernel(0.3, (1e-4, 1e1)) * Matern(
                     scales, bounds, nu=1.5)}[s['kernel']]
        return (ConstantKernel(1.0, (1e-3, 1e3)) * shape
                + WhiteKernel(s['noise_level'], tuple(s['noise_bounds'])))

    _payload_varies = False     # the last normalised input is a payload that varied in training

    def fit(self, joints: np.ndarray, deflections: np.ndarray,
            payload: np.ndarray | None = None) -> GpPredictor:
        self._payload_varies = bool(self.settings['payload_input'] and payload is not None
                                    and np.ptp(np.asarray(payload, dtype=float)) > 0)
        return super().fit(joints, deflections, payload)

    def _fit_normalised(self, x: np.ndarray, y: np.ndarray) -> None:
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.gaussian_process import GaussianProcessRegressor

        with warnings.catch_warnings():
            warnings.simplefilter('ignore', ConvergenceWarning)   # hyperparameter at a bound
            self._gps = [GaussianProcessRegressor(
                self._kernel(x.shape[1]), n_restarts_optimizer=self.settings['restarts'],
                random_state=self.settings['seed'] + k).fit(x, y[:, k]) for k in range(OUTPUTS)]
        self._x, self._y = x, y

    def _predict_normalised(self, x: np.ndarray) -> np.ndarray:
        return np.column_stack([gp.predict(x) for gp in self._gps])

    def predict_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                    ) -> np.ndarray:
        """Predictive standard deviation [m, m, rad], shaped like :meth:`predict`."""
        x, single = self._inputs(joints, payload)
        normalisation = self._require_fitted()
        z = normalisation.inputs(x)
        std = np.column_stack([gp.predict(z, return_std=True)[1] for gp in self._gps])
        std = std * normalisation.output_std
        return std[0] if single else std

    def position_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                     ) -> np.ndarray | float:
        std = np.asarray(self.predict_std(joints, payload))
        position = np.hypot(std[..., 0], std[..., 1])
        return float(position) if position.ndim == 0 else position

    def _state(self) -> dict[str, np.ndarray]:
        return {'x': self._x, 'y': self._y,
                'theta': np.stack([gp.kernel_.theta for gp in self._gps])}

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        from sklearn.gaussian_process import GaussianProcessRegressor

        self._x = np.asarray(state['x'], dtype=float)
        self._y = np.asarray(state['y'], dtype=float)
        self._payload_varies = bool(self.settings['payload_input']
                                    and self.metadata['normalisation']['active_inputs'][-1])
        kernel = self._kernel(self._x.shape[1])
        self._gps = [GaussianProcessRegressor(kernel.clone_with_theta(theta), optimizer=None)
                     .fit(self._x, self._y[:, k]) for k, theta in enumerate(state['theta'])]
