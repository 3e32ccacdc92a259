"""Multilayer perceptron predictor: a deep ensemble (Lakshminarayanan et al. 2017) of the
paper's network (one hidden layer of 10 units, tanh, linear outputs).

``members`` networks (default 5), each Glorot-uniform initialised from one generator seeded
with ``seed`` (a fit is deterministic for a seed), are trained on the same normalised data:
full-batch L-BFGS with a strong-Wolfe line search, float64, at most ``max_iterations``
iterations, on the mean squared error of the normalised outputs plus ``weight_decay`` × Σ w²
over the weight matrices. The ensemble predicts its members' mean; their spread
(:meth:`MlpPredictor.deflection_std`) is the model's raw uncertainty: the members agree where
the data pin the function down and part away from it. The learner calibrates it on held-out
samples into a 95 % bound (:mod:`..error_bound`).

Training uses torch (the user's choice: autograd and its L-BFGS), imported in the fit only.
All members form one batched network (weights (members, n_out, n_in)) under the sum of their
losses: the loss separates, so each member's minimum is its own; only the shared line search
and curvature pairs couple their paths (after 1000 iterations each member's loss was within
3 % of training it alone, in a third of the time). One thread: the matrices are tiny. An
ensemble fit of 40 samples (4 inputs, 10 hidden, 5 members, 1000 iterations) took 0.66-1.09 s
(median 0.76 s) of wall time on a busy 2-core machine; a process's first fit also imports
torch (1.6-3.6 s) and torch._dynamo (~1.7 s; torch.optim does). Prediction is numpy on the
exported weights (~25 µs a query), so the compensator that loads a model never imports torch;
the model file holds the weights as arrays ``weight{i}`` (members, n_out, n_in) and
``bias{i}`` (members, n_out).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from flexarm_deflection.predictors.base import OUTPUTS, Predictor

if TYPE_CHECKING:
    import torch


def _expit(x: np.ndarray) -> np.ndarray:
    """scipy's logistic function, imported where used (predictors/base.py)."""
    from scipy.special import expit

    return expit(x)


# Per layer: weight (members, n_out, n_in), bias (members, n_out).
Layers = list[tuple[np.ndarray, np.ndarray]]

ACTIVATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    'tanh': np.tanh,
    'sigmoid': _expit,
    'relu': lambda x: np.maximum(x, 0.0),
    'softplus': lambda x: np.logaddexp(0.0, x),
}


def forward(layers: Layers, activation: str, x: np.ndarray) -> np.ndarray:
    """Outputs (members, N, 3) of every member of the ensemble at inputs x (N, d)."""
    function = ACTIVATIONS[activation]
    h = x
    for i, (weight, bias) in enumerate(layers):
        h = h @ np.swapaxes(weight, 1, 2) + bias[:, np.newaxis]
        if i < len(layers) - 1:
            h = function(h)
    return h


def torch_forward(parameters: list[torch.Tensor], activation: str, x: torch.Tensor,
                  ) -> torch.Tensor:
    """:func:`forward` in torch on [weight0, bias0, weight1, ...]: the network trained."""
    import torch

    function = {'tanh': torch.tanh, 'sigmoid': torch.sigmoid, 'relu': torch.relu,
                'softplus': lambda z: torch.logaddexp(z, torch.zeros_like(z))}[activation]
    h = x.expand(len(parameters[0]), *x.shape)
    for i in range(0, len(parameters), 2):
        h = torch.baddbmm(parameters[i + 1].unsqueeze(1), h, parameters[i].transpose(1, 2))
        if i < len(parameters) - 2:
            h = function(h)
    return h


def initial_layers(sizes: list[int], members: int, rng: np.random.Generator) -> Layers:
    """Glorot-uniform weights and zero biases of ``members`` networks of ``sizes`` units."""
    layers = []
    for n_in, n_out in zip(sizes[:-1], sizes[1:]):
        bound = np.sqrt(6.0 / (n_in + n_out))
        layers.append((rng.uniform(-bound, bound, (members, n_out, n_in)),
                       np.zeros((members, n_out))))
    return layers


def train(layers: Layers, x: np.ndarray, y: np.ndarray, activation: str, decay: float,
          iterations: int) -> Layers:
    """The ensemble ``layers`` trained on inputs x (N, d) and outputs y (N, 3) (module
    docstring), on one torch thread: more only wait on matrices this small."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return _minimise(layers, x, y, activation, decay, iterations)
    finally:
        torch.set_num_threads(threads)


def _minimise(layers: Layers, x: np.ndarray, y: np.ndarray, activation: str, decay: float,
              iterations: int) -> Layers:
    """:func:`train`'s work: one L-BFGS run on the summed loss; ValueError if it diverged."""
    import torch

    parameters = [torch.tensor(array, dtype=torch.float64, requires_grad=True)
                  for layer in layers for array in layer]
    inputs = torch.as_tensor(x, dtype=torch.float64)
    targets = torch.as_tensor(y, dtype=torch.float64)
    # scipy L-BFGS-B's history of 10; no stop on a small change of the loss (as its ftol 0);
    # evaluations enough for the line search's extra ones (~3 % of the iterations)
    optimiser = torch.optim.LBFGS(parameters, max_iter=iterations, max_eval=2 * iterations,
                                  tolerance_grad=1e-10, tolerance_change=0.0, history_size=10,
                                  line_search_fn='strong_wolfe')

    def closure() -> torch.Tensor:
        """The members' losses summed: each one's mean squared error and weight decay."""
        optimiser.zero_grad()
        error = torch_forward(parameters, activation, inputs) - targets
        loss = error.pow(2).sum() / y.size + decay * sum(w.pow(2).sum() for w in parameters[::2])
        loss.backward()
        return loss

    optimiser.step(closure)
    trained = [p.detach().numpy().copy() for p in parameters]
    if not all(np.isfinite(array).all() for array in trained):
        raise ValueError('mlp training diverged')
    return list(zip(trained[::2], trained[1::2]))


class MlpPredictor(Predictor):
    """Ensemble of ``members`` fully connected networks, ``hidden`` units per hidden layer,
    linear output layer."""

    kind: ClassVar[str] = 'mlp'
    defaults: ClassVar[dict[str, Any]] = {
        'hidden': [10], 'activation': 'tanh', 'weight_decay': 1e-4, 'members': 5,
        'max_iterations': 1000, 'seed': 0, 'payload_input': False}
    cv_choices: ClassVar[dict[str, list[Any]]] = {'weight_decay': [1e-5, 1e-4, 1e-3]}
    # No cv_overrides: the cross-validation fits keep all members. The learner calibrates the
    # model's spread by theirs, so they must have as many; and fewer save little, as a fit's
    # time goes to the L-BFGS iterations' torch calls (2 members took 95 % of the CPU of 5).

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
        if s['members'] < 2:
            raise ValueError("mlp 'members' must be >= 2: the ensemble's spread needs two")
        if s['max_iterations'] < 1:
            raise ValueError("mlp 'max_iterations' must be >= 1")

    def _fit_normalised(self, x: np.ndarray, y: np.ndarray) -> None:
        s = self.settings
        sizes = [x.shape[1], *s['hidden'], OUTPUTS]
        layers = initial_layers(sizes, s['members'], np.random.default_rng(s['seed']))
        self._layers = train(layers, x, y, s['activation'], s['weight_decay'],
                             s['max_iterations'])

    def _predict_normalised(self, x: np.ndarray) -> np.ndarray:
        return forward(self._layers, self.settings['activation'], x).mean(axis=0)

    def deflection_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                       ) -> np.ndarray:
        """The members' standard deviation (ddof 1) of the deflection [m, m, rad], shaped like
        :meth:`predict`; the corrections of a refresh shift every member alike."""
        x, single = self._inputs(joints, payload)
        normalisation = self._require_fitted()
        outputs = forward(self._layers, self.settings['activation'], normalisation.inputs(x))
        std = outputs.std(axis=0, ddof=1) * normalisation.output_std
        return std[0] if single else std

    def _state(self) -> dict[str, np.ndarray]:
        state = {}
        for i, (weight, bias) in enumerate(self._layers):
            state[f'weight{i}'], state[f'bias{i}'] = weight, bias
        return state

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        s = self.settings
        inputs = int(self._require_fitted().active_inputs.sum())
        sizes = [inputs, *s['hidden'], OUTPUTS]
        self._layers = []
        for i, (n_in, n_out) in enumerate(zip(sizes[:-1], sizes[1:])):
            weight = np.asarray(state[f'weight{i}'], dtype=float)
            bias = np.asarray(state[f'bias{i}'], dtype=float)
            if weight.shape != (s['members'], n_out, n_in) or bias.shape != (s['members'], n_out):
                raise ValueError(f'layer {i}: weight {weight.shape}, bias {bias.shape} for '
                                 f"{s['members']} members of {n_in} → {n_out} units")
            self._layers.append((weight, bias))
