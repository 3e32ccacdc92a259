"""Fitting of the MLP predictor (:mod:`.mlp`; method in its docstring): the only module that
imports torch, and only imported to fit, so that loading a model and predicting never pay
torch's ~0.7 s import.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import torch
from scipy.optimize import minimize

from flexarm_control.predictors.base import OUTPUTS

ACTIVATIONS: dict[str, Callable[[torch.Tensor], torch.Tensor]] = {
    'tanh': torch.tanh, 'sigmoid': torch.sigmoid, 'relu': torch.relu,
    'softplus': torch.nn.functional.softplus}


def train(x: np.ndarray, y: np.ndarray, settings: Mapping[str, Any],
          ) -> list[tuple[np.ndarray, np.ndarray]]:
    """(weight, bias) per layer of the network fitted to normalised inputs (N, d) and outputs
    (N, 3), with the MLP's ``settings``; ValueError if every restart diverged."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return _train(torch.from_numpy(x), torch.from_numpy(y), settings)
    finally:
        torch.set_num_threads(threads)


def _train(x: torch.Tensor, y: torch.Tensor, settings: Mapping[str, Any],
           ) -> list[tuple[np.ndarray, np.ndarray]]:
    activation = ACTIVATIONS[settings['activation']]
    decay = settings['weight_decay']
    sizes = [x.shape[1], *settings['hidden'], OUTPUTS]
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

    generator = torch.Generator().manual_seed(settings['seed'])
    best = None
    for _ in range(settings['restarts']):
        result = minimize(objective, _initial_parameters(sizes, generator), jac=True,
                          method='L-BFGS-B', options={
                              'maxiter': settings['max_iterations'], 'ftol': 0.0,
                              'gtol': 1e-10})
        if np.isfinite(result.fun) and (best is None or result.fun < best.fun):
            best = result
    if best is None:
        raise ValueError('mlp training diverged in every restart')
    params = [p.numpy().copy() for p in _unflatten(torch.from_numpy(best.x), shapes)]
    return list(zip(params[::2], params[1::2]))


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
