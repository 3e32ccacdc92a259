"""Multilayer perceptron predictor (the paper's network: one hidden layer of 10 units).

Full-batch L-BFGS (scipy's L-BFGS-B, at most ``max_iterations`` iterations) on the mean squared
error of the normalised outputs plus ``weight_decay`` × Σ w² over the weight matrices; loss and
gradient by backpropagation written out in numpy (:func:`objective`): for a network of ~100
weights on tens of samples an evaluation takes ~50 µs where torch autograd took ~300 µs, and
fitting imports no torch (~1 s). Several random restarts (Glorot-uniform weights drawn
from a generator seeded with ``seed``) are trained and the one with the lowest final objective
is kept, so a fit is deterministic for a seed. Defaults: 1000 iterations, 4 restarts (1 in the
learner's cross-validation fits), weight decay 1e-4 unless the learner chooses it by
cross-validation: the earlier 300 iterations and 1e-5 trained faster but missed more targets of
a region. The model file holds the weights as numpy arrays.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np

from flexarm_control.learning.predictors.base import OUTPUTS, Predictor


def _expit(x: np.ndarray) -> np.ndarray:
    """scipy's logistic function, imported where used (predictors/base.py)."""
    from scipy.special import expit

    return expit(x)


Layers = list[tuple[np.ndarray, np.ndarray]]    # (weight (n_out, n_in), bias (n_out,))

ACTIVATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    'tanh': np.tanh,
    'sigmoid': _expit,
    'relu': lambda x: np.maximum(x, 0.0),
    'softplus': lambda x: np.logaddexp(0.0, x),
}
# Their derivatives, from the input z and the activation's value a there.
DERIVATIVES: dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]] = {
    'tanh': lambda z, a: 1.0 - a ** 2,
    'sigmoid': lambda z, a: a * (1.0 - a),
    'relu': lambda z, a: (z > 0).astype(float),
    'softplus': lambda z, a: _expit(z),
}


def forward(layers: Layers, activation: str, x: np.ndarray,
            ) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """Outputs (N, 3) of the network at inputs x (N, d), with each hidden layer's input sums
    and activations."""
    function = ACTIVATIONS[activation]
    sums, values, h = [], [], x
    for weight, bias in layers[:-1]:
        sums.append(h @ weight.T + bias)
        h = function(sums[-1])
        values.append(h)
    weight, bias = layers[-1]
    return h @ weight.T + bias, sums, values


def objective(flat: np.ndarray, x: np.ndarray, y: np.ndarray, sizes: list[int],
              activation: str, decay: float) -> tuple[float, np.ndarray]:
    """Training loss at the parameters ``flat`` (:func:`unflatten`) and its gradient."""
    layers = unflatten(flat, sizes)
    out, sums, values = forward(layers, activation, x)
    error = out - y
    loss = float(np.mean(error ** 2) + decay * sum(np.sum(w ** 2) for w, _ in layers))
    inputs = [x, *values]
    grads: list[np.ndarray] = [np.empty(0)] * (2 * len(layers))
    delta = 2.0 * error / error.size               # d loss / d the sums of the layer
    for i in range(len(layers) - 1, -1, -1):
        weight = layers[i][0]
        grads[2 * i] = delta.T @ inputs[i] + 2.0 * decay * weight
        grads[2 * i + 1] = delta.sum(axis=0)
        if i:
            delta = (delta @ weight) * DERIVATIVES[activation](sums[i - 1], values[i - 1])
    return loss, np.concatenate([g.ravel() for g in grads])


def unflatten(flat: np.ndarray, sizes: list[int]) -> Layers:
    """The layers of a network of ``sizes`` units from one vector [w0, b0, w1, b1, ...]."""
    layers, start = [], 0
    for n_in, n_out in zip(sizes[:-1], sizes[1:]):
        weight = flat[start:start + n_out * n_in].reshape(n_out, n_in)
        start += n_out * n_in
        layers.append((weight, flat[start:start + n_out]))
        start += n_out
    return layers


def _initial_parameters(sizes: list[int], rng: np.random.Generator) -> np.ndarray:
    """Glorot-uniform weights and zero biases, flattened as [w0, b0, w1, b1, ...]."""
    parts = []
    for n_in, n_out in zip(sizes[:-1], sizes[1:]):
        bound = np.sqrt(6.0 / (n_in + n_out))
        parts += [rng.uniform(-bound, bound, n_out * n_in), np.zeros(n_out)]
    return np.concatenate(parts)


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
        from scipy import optimize

        s = self.settings
        sizes = [x.shape[1], *s['hidden'], OUTPUTS]
        rng = np.random.default_rng(s['seed'])
        best = None
        for _ in range(s['restarts']):
            result = optimize.minimize(objective, _initial_parameters(sizes, rng),
                              (x, y, sizes, s['activation'], s['weight_decay']), jac=True,
                              method='L-BFGS-B', options={
                                  'maxiter': s['max_iterations'], 'ftol': 0.0, 'gtol': 1e-10})
            if np.isfinite(result.fun) and (best is None or result.fun < best.fun):
                best = result
        if best is None:
            raise ValueError('mlp training diverged in every restart')
        self._layers = unflatten(best.x, sizes)

    def _predict_normalised(self, x: np.ndarray) -> np.ndarray:
        return forward(self._layers, self.settings['activation'], x)[0]

    def _state(self) -> dict[str, np.ndarray]:
        state = {}
        for i, (weight, bias) in enumerate(self._layers):
            state[f'weight{i}'], state[f'bias{i}'] = weight, bias
        return state

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        layers = len(self.settings['hidden']) + 1
        self._layers = [(np.asarray(state[f'weight{i}'], dtype=float),
                         np.asarray(state[f'bias{i}'], dtype=float)) for i in range(layers)]
