"""Multilayer perceptron predictor (the paper's network: one hidden layer of 10 units).

Full-batch L-BFGS (scipy's L-BFGS-B, at most ``max_iterations`` iterations) on the mean squared
error of the normalised outputs plus ``weight_decay`` × Σ w² over the weight matrices; loss and
gradient come from torch autograd (CPU, float64, one thread). scipy's optimiser instead of
``torch.optim`` saves the ~1.4 s first-use import of ``torch._dynamo``. Several random restarts
(Glorot-uniform weights drawn from a generator seeded with ``seed``) are trained and the one
with the lowest final objective is kept, so a fit is deterministic for a seed. Defaults: 1000
iterations, 4 restarts (1 in the learner's cross-validation fits), weight decay 1e-4 unless the
learner chooses it by cross-validation: the earlier 300 iterations and 1e-5 trained faster but
missed more targets of a region. Prediction runs the same network in numpy (cheaper per single
query than torch).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np
import torch
from scipy.optimize import minimize
from scipy.special import expit

from flexarm_control.predictors.base import OUTPUTS, Predictor

ACTIVATIONS: dict[str, tuple[Callable[[torch.Tensor], torch.Tensor],
                             Callable[[np.ndarray], np.ndarray]]] = {
    'tanh': (torch.tanh, np.tanh),
    'sigmoid': (torch.sigmoid, expit),
    'relu': (torch.relu, lambda x: np.maximum(x, 0.0)),
    'softplus': (torch.nn.functional.softplus, lambda x: np.logaddexp(0.0, x)),
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
        threads = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            self._layers = self._train(torch.from_numpy(x), torch.from_numpy(y))
        finally:
            torch.set_num_threads(threads)

    def _train(self, x: torch.Tensor, y: torch.Tensor) -> list[tuple[np.ndarray, np.ndarray]]:
        activation = ACTIVATIONS[self.settings['activation']][0]
        decay = self.settings['weight_decay']
        sizes = [x.shape[1], *self.settings['hidden'], OUTPUTS]
        shapes = [shape for n_in, n_out in zip(sizes[:-1], sizes[1:])
                  for shape in ((n_out, n_in), (n_out,))]

        def objective(flat: np.ndarray) -> tuple[float, np.ndarray]:
            """Loss and its gradient for all parameters as one vector."""
            theta = torch.from_numpy(flat).requires_grad_()
            params = _unflatten(theta, shapes)
            h = x
            for i in range(0, len(params) - 2, 2):
                h = activation(torch.addmm(params[i + 1], h, params[i].T))
            out = torch.addmm(params[-1], h, params[-2].T)
            loss = ((out - y) ** 2).mean() + decay * sum((w ** 2).sum() for w in params[::2])
            loss.backward()
            return float(loss.detach()), theta.grad.numpy()

        generator = torch.Generator().manual_seed(self.settings['seed'])
        best = None
        for _ in range(self.settings['restarts']):
            result = minimize(objective, _initial_parameters(sizes, generator), jac=True,
                              method='L-BFGS-B', options={
                                  'maxiter': self.settings['max_iterations'], 'ftol': 0.0,
                                  'gtol': 1e-10})
            if np.isfinite(result.fun) and (best is None or result.fun < best.fun):
                best = result
        if best is None:
            raise ValueError('mlp training diverged in every restart')
        params = [p.numpy().copy() for p in _unflatten(torch.from_numpy(best.x), shapes)]
        return list(zip(params[::2], params[1::2]))

    def _predict_normalised(self, x: np.ndarray) -> np.ndarray:
        activation = ACTIVATIONS[self.settings['activation']][1]
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


def _initial_parameters(sizes: list[int], generator: torch.Generator) -> np.ndarray:
    """Glorot-uniform weights and zero biases, flattened as [w0, b0, w1, b1, ...]."""
    parts = []
    for n_in, n_out in zip(sizes[:-1], sizes[1:]):
        bound = np.sqrt(6.0 / (n_in + n_out))
        weight = torch.rand(n_out * n_in, generator=generator, dtype=torch.float64) * 2 - 1
        parts += [weight.numpy() * bound, np.zeros(n_out)]
    return np.concatenate(parts)


def _unflatten(flat: torch.Tensor, shapes: list[tuple[int, ...]]) -> list[torch.Tensor]:
    """Views of a flat parameter vector with the given shapes."""
    params, start = [], 0
    for shape in shapes:
        size = int(np.prod(shape))
        params.append(flat[start:start + size].view(shape))
        start += size
    return params
