"""What the physics leaves, learned by a deep ensemble (Lakshminarayanan et al. 2017) of small
networks on all joints at once: the JAERI paper's approach, beside the joint-error GP.

``MEMBERS`` networks (joints → ``HIDDEN`` tanh units → ``HIDDEN`` tanh units → 3), each
initialised from one seeded generator, trained together as one batched network on the
z-scored joints and residual: full-batch L-BFGS (torch's, with its strong-Wolfe line search,
float64) on the mean squared error plus ``WEIGHT_DECAY`` × Σ w². Their mean is the prediction,
their spread (with the training residual's scatter, which a new measurement has too) the raw
uncertainty the conformal radius scales. torch is imported in the fit only.

It learns what varies smoothly over all joints together; an error of one joint's own angle at
a short scale (the UR10's, :mod:`.joint_error`) it cannot resolve from a few hundred rows: on
the UR10 of ../shared/data it left as much as the physics alone (``flexarm accuracy --kinds
greybox,mlp,elastostatic``, series D, 200 rows: 0.31 mm against 0.31 and the greybox's 0.13).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

MEMBERS = 5
HIDDEN = 32
WEIGHT_DECAY = 1e-2     # 1e-3 overfit: 30 % above the physics alone on held-out rows
ITERATIONS = 300


class ResidualMlp:
    """The ensemble, fitted on rows of joints (N, n) and residual points (N, 3) [m]."""

    def fit(self, joints: np.ndarray, residual: np.ndarray, seed: int = 0) -> ResidualMlp:
        import torch

        self._mean, self._std = joints.mean(axis=0), joints.std(axis=0) + 1e-12
        self._out_mean, self._out_std = residual.mean(axis=0), residual.std(axis=0) + 1e-12
        x = torch.as_tensor((joints - self._mean) / self._std)
        y = torch.as_tensor((residual - self._out_mean) / self._out_std)
        generator = torch.Generator().manual_seed(seed)
        sizes = (joints.shape[1], HIDDEN, HIDDEN, 3)
        params = []
        for n_in, n_out in zip(sizes[:-1], sizes[1:]):
            bound = float(np.sqrt(6.0 / (n_in + n_out)))        # Glorot uniform
            weight = (torch.rand(MEMBERS, n_out, n_in, generator=generator,
                                 dtype=torch.float64) * 2 - 1) * bound
            params += [weight.requires_grad_(), torch.zeros(MEMBERS, n_out, 1,
                                                            dtype=torch.float64,
                                                            requires_grad=True)]
        optimiser = torch.optim.LBFGS(params, max_iter=ITERATIONS, line_search_fn='strong_wolfe',
                                      tolerance_grad=1e-9, tolerance_change=1e-12)

        def loss() -> torch.Tensor:
            optimiser.zero_grad()
            out = _forward(params, x.T.unsqueeze(0), torch.tanh)
            value = (((out - y.T.unsqueeze(0)) ** 2).mean(dim=(1, 2)).sum()
                     + WEIGHT_DECAY * sum((w ** 2).sum() for w in params[::2]))
            value.backward()
            return value

        with _OneThread(torch):
            optimiser.step(loss)
        self._layers = [p.detach().numpy() for p in params]
        fitted = self._members(joints).mean(axis=0)
        self.noise = float(np.sqrt(np.mean((fitted - residual) ** 2)))
        return self

    def _members(self, joints: np.ndarray) -> np.ndarray:
        """(members, N, 3) [m]: every member's prediction."""
        x = ((joints - self._mean) / self._std).T[None]
        out = _forward(self._layers, x, np.tanh)
        return np.moveaxis(out, 1, 2) * self._out_std + self._out_mean

    def predict(self, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean (M, 3) [m] and covariance (M, 3, 3) [m²]: the members' spread per axis and
        the training residual's scatter."""
        members = self._members(np.atleast_2d(joints))
        variance = members.var(axis=0) + self.noise ** 2
        return members.mean(axis=0), variance[:, :, None] * np.eye(3)


def _forward(layers: list, x: Any, activation: Callable[[Any], Any]) -> Any:
    """Batched network (torch tensors or numpy arrays alike): x (1, n_in, N) → (members,
    3, N)."""
    h = x
    for i in range(0, len(layers), 2):
        h = layers[i] @ h + layers[i + 1]
        if i < len(layers) - 2:
            h = activation(h)
    return h


class _OneThread:
    """torch on one thread for the fit (the matrices are tiny), restored after."""

    def __init__(self, torch) -> None:
        self._torch, self._threads = torch, torch.get_num_threads()

    def __enter__(self) -> None:
        self._torch.set_num_threads(1)

    def __exit__(self, *exc) -> None:
        self._torch.set_num_threads(self._threads)
