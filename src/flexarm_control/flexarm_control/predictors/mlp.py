"""Multilayer perceptron predictor (the paper's network: one hidden layer of 10 units).

Full-batch L-BFGS (scipy's L-BFGS-B, at most ``max_iterations`` iterations) on the mean squared
error of the normalised outputs plus ``weight_decay`` × Σ w² over the weight matrices; loss and
gradient come from torch autograd (CPU, float64, one thread) in :mod:`.mlp_training`, imported
only to fit. scipy's optimiser instead of ``torch.optim`` saves the ~1.4 s first-use import of
``torch._dynamo``. Several random restarts (Glorot-uniform weights drawn from a generator
seeded with ``seed``) are trained and the one with the lowest final objective is kept, so a fit
is deterministic for a seed. Defaults: 1000 iterations, 4 restarts (1 in the learner's
cross-validation fits), weight decay 1e-4 unless the learner chooses it by cross-validation:
the earlier 300 iterations and 1e-5 trained faster but missed more targets of a region.
Prediction runs the same network in numpy (cheaper per single query than torch), and the model
file holds its weights as numpy arrays: loading a model and predicting never import torch.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np
from scipy.special import expit

from flexarm_control.predictors.base import Predictor

ACTIVATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    'tanh': np.tanh,
    'sigmoid': expit,
    'relu': lambda x: np.maximum(x, 0.0),
    'softplus': lambda x: np.logaddexp(0.0, x),
}


class MlpPredictor(Predictor):
    """Fully connected network, ``hidden`` units per hidden layer, linear output layer."""

    kind: ClassVar[str] = 'mlp'
    defaults: ClassVar[dict[str, Any]] = {
        'hidden': [10], 'activation': 'tanh', 'weight_decay': 1e-4, 'restarts': 4,
        'max_iterations': 1000, 'seed': 0, 'payload_input': False}
    cv_choices: ClassVar[dict[str, list[Any]]] = {'weight_decay': [1e-5, 1e-4, 1e-3]}
    cv_overrides: ClassVar[dict[str, Any]] = {'restarts': 1}

    def _check_settings(self) -> None:
        s = self.settings
        if not s['hidden'] or min(s['hidden']) < 1:
            raise ValueError(f"mlp 'hidden' needs at least one layer of >= 1 unit, "
                             f"got {s['hidden']}")
        if s['activation'] not in ACTIVATIONS:
            raise ValueError(f"mlp 'activation' must be one of {sorted(ACTIVATIONS)}, "
                             f"got {s['activation']!r}")
        if s['weight_decay'] < 0:
            raise ValueError("mlp 'weight_decay' must be >= 0")
        if s['restarts'] < 1 or s['max_iterations'] < 1:
            raise ValueError("mlp 'restarts' and 'max_iterations' must be >= 1")

    def _fit_normalised(self, x: np.ndarray, y: np.ndarray) -> None:
        from flexarm_control.predictors.mlp_training import train  # torch: only to fit

        self._layers = train(x, y, self.settings)

    def _predict_normalised(self, x: np.ndarray) -> np.ndarray:
        activation = ACTIVATIONS[self.settings['activation']]
        h = x
        for weight, bias in self._layers[:-1]:
            h = activation(h @ weight.T + bias)
        weight, bias = self._layers[-1]
        return h @ weight.T + bias

    def _state(self) -> dict[str, np.ndarray]:
        state = {}
        for i, (weight, bias) in enumerate(self._layers):
            state[f'weight{i}'], state[f'bias{i}'] = weight, bias
        return state

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        layers = len(self.settings['hidden']) + 1
        self._layers = [(np.asarray(state[f'weight{i}'], dtype=float),
                         np.asarray(state[f'bias{i}'], dtype=float)) for i in range(layers)]

