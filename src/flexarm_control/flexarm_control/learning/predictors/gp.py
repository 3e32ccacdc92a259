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

In numpy, what scikit-learn's ``GaussianProcessRegressor`` computes (same kernels, bounds,
initial values, seeded restarts, L-BFGS-B on the log marginal likelihood and its analytic
gradient, :func:`negative_log_likelihood`): its kernel objects spent ~1 ms of a likelihood
evaluation handling parameters, 5× the arithmetic for 50 samples, and its prediction ~150 µs
validating the input per output. Nor does loading and querying a model (the compensator)
import scikit-learn (~0.5 s).

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

from flexarm_control.learning.predictors.base import OUTPUTS, Predictor

KERNELS = ('rbf', 'matern52', 'matern32', 'rbf+matern32')
# Correlation families summed in each kernel; the second and later with an amplitude of their
# own (initial value and bounds below).
FAMILIES = {'rbf': ('rbf',), 'matern52': ('matern52',), 'matern32': ('matern32',),
            'rbf+matern32': ('rbf', 'matern32')}
CONSTANT, CONSTANT_BOUNDS = 1.0, (1e-3, 1e3)     # the overall amplitude
PART, PART_BOUNDS = 0.3, (1e-4, 1e1)             # amplitude of a family after the first
JITTER = 1e-10     # added to the covariance's diagonal: scikit-learn's default ``alpha``


def _correlation(family: str, r2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Correlation at squared scaled distances ``r2``, and its derivative by the log of an
    input's length scale divided by that input's squared scaled distance."""
    if family == 'rbf':
        s = np.exp(-0.5 * r2)
        return s, s
    if family == 'matern32':
        r = np.sqrt(3.0 * r2)
        e = np.exp(-r)
        return (1.0 + r) * e, 3.0 * e
    r = np.sqrt(5.0 * r2)
    e = np.exp(-r)
    return (1.0 + r + r ** 2 / 3.0) * e, 5.0 / 3.0 * (1.0 + r) * e


def _parts(kernel: str, theta: np.ndarray, inputs: int,
           ) -> tuple[np.ndarray, list[tuple[str, np.ndarray, np.ndarray]], np.ndarray]:
    """Constant, (family, amplitude, length scales) per family, and noise level of
    log-hyperparameters ``theta`` (..., p): [constant, scales, (amplitude, scales)..., noise]."""
    p = np.exp(theta)
    families, i = [], 1
    for j, family in enumerate(FAMILIES[kernel]):
        amplitude = np.ones(p.shape[:-1])
        if j:
            amplitude, i = p[..., i], i + 1
        families.append((family, amplitude, p[..., i:i + inputs]))
        i += inputs
    return p[..., 0], families, p[..., -1]


Side = list[tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]


def one_side(kernel: str, theta: np.ndarray, b: np.ndarray) -> Side:
    """What a covariance with inputs ``b`` (N, d) needs of them and of K sets of
    log-hyperparameters ``theta`` (K, p) (:func:`_parts`), per correlation family: (family,
    weight (K,), length scales (K, d), scaled inputs (K, N, d), their squared norms (K, N)).
    A GP keeps its training side: a query then costs a third less."""
    constant, families, _ = _parts(kernel, theta, b.shape[1])
    side = []
    for family, amplitude, scales in families:
        scaled = b / scales[:, None]
        side.append((family, constant * amplitude, scales, scaled, (scaled ** 2).sum(axis=2)))
    return side


def cross_covariance(side: Side, a: np.ndarray) -> np.ndarray:
    """Noise-free covariance (K, M, N) of inputs ``a`` (M, d) with the inputs of ``side``.
    Squared distances as |a|² + |b|² − 2 a·b, one matrix product for one query or a
    thousand, and in place: on this machine a fresh array of a thousand queries' costs more
    in page faults than the arithmetic."""
    terms = []
    for family, weight, scales, scaled, norms in side:
        sa = a / scales[:, None]
        r2 = sa @ scaled.transpose(0, 2, 1)
        r2 *= -2.0
        r2 += (sa ** 2).sum(axis=2)[:, :, None]
        r2 += norms[:, None]
        correlation = _correlation(family, np.maximum(r2, 0.0, out=r2))[0]
        correlation *= weight[:, None, None]
        terms.append(correlation)
    return sum(terms[1:], terms[0])


def negative_log_likelihood(theta: np.ndarray, kernel: str, squares: np.ndarray,
                            y: np.ndarray) -> tuple[float, np.ndarray]:
    """−log marginal likelihood of outputs y (N,) and its gradient by ``theta``, with
    ``squares`` (N, N, d) the squared differences of the training inputs per input; +inf
    where the covariance is not positive definite (as scikit-learn)."""
    from scipy import linalg

    constant, families, noise = _parts(kernel, theta, squares.shape[2])
    terms = []
    for family, amplitude, scales in families:
        inverse = scales ** -2.0
        s, slope = _correlation(family, squares @ inverse)
        terms.append((amplitude, s, slope, inverse))
    shape = sum(amplitude * s for amplitude, s, _, _ in terms)
    n = len(y)
    k = constant * shape
    k[np.diag_indices(n)] += noise + JITTER
    try:
        lower = linalg.cholesky(k, lower=True, check_finite=False)
    except linalg.LinAlgError:
        return np.inf, np.zeros_like(theta)
    alpha = linalg.cho_solve((lower, True), y, check_finite=False)
    value = 0.5 * y @ alpha + np.log(np.diag(lower)).sum() + 0.5 * n * np.log(2 * np.pi)
    inner = np.outer(alpha, alpha) - linalg.cho_solve((lower, True), np.eye(n),
                                                      check_finite=False)
    gradient = [constant * np.sum(inner * shape)]
    for j, (amplitude, s, slope, inverse) in enumerate(terms):
        if j:
            gradient.append(constant * amplitude * np.sum(inner * s))
        gradient.extend(constant * amplitude * inverse
                        * np.einsum('ij,ijd->d', inner * slope, squares))
    gradient.append(noise * np.trace(inner))
    return value, -0.5 * np.array(gradient)


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
        """Initial log-hyperparameters (p,) and their bounds (p, 2) (:func:`_parts`)."""
        s = self.settings
        bounds = np.tile(s['length_scale_bounds'], (inputs, 1))
        if self._payload_varies:
            bounds[-1, 0] = min(s['payload_length_scale'], bounds[-1, 1])
        scales = np.maximum(1.0, bounds[:, 0])
        values, limits = [[CONSTANT]], [[CONSTANT_BOUNDS]]
        for j, _ in enumerate(FAMILIES[s['kernel']]):
            if j:
                values.append([PART])
                limits.append([PART_BOUNDS])
            values.append(scales)
            limits.append(bounds)
        values.append([s['noise_level']])
        limits.append([s['noise_bounds']])
        return np.log(np.concatenate(values)), np.log(np.concatenate(limits))

    _payload_varies = False     # the last normalised input is a payload that varied in training

    def fit(self, joints: np.ndarray, deflections: np.ndarray,
            payload: np.ndarray | None = None) -> GpPredictor:
        self._payload_varies = bool(self.settings['payload_input'] and payload is not None
                                    and np.ptp(np.asarray(payload, dtype=float)) > 0)
        return super().fit(joints, deflections, payload)

    def _fit_normalised(self, x: np.ndarray, y: np.ndarray) -> None:
        from scipy import optimize

        theta0, bounds = self._hyperparameters(x.shape[1])
        squares = (x[:, None, :] - x[None, :, :]) ** 2
        theta = []
        for k in range(OUTPUTS):      # restarts drawn in the bounds as scikit-learn draws them
            rng = np.random.RandomState(self.settings['seed'] + k)
            starts = [theta0] + [rng.uniform(bounds[:, 0], bounds[:, 1])
                                 for _ in range(self.settings['restarts'])]
            optima = [optimize.minimize(negative_log_likelihood, start,
                                        (self.settings['kernel'], squares, y[:, k]),
                                        method='L-BFGS-B', jac=True, bounds=bounds)
                      for start in starts]
            theta.append(min(optima, key=lambda result: result.fun).x)
        self._condition(x, y, np.stack(theta))

    def _condition(self, x: np.ndarray, y: np.ndarray, theta: np.ndarray) -> None:
        """The posterior of every output given training data and hyperparameters (K, p)."""
        from scipy import linalg

        self._x, self._y, self._theta = x, y, theta
        self._side = one_side(self.settings['kernel'], theta, x)
        noise = np.exp(theta[:, -1]) + JITTER
        k = cross_covariance(self._side, x) + noise[:, None, None] * np.eye(len(x))
        self._cholesky = np.linalg.cholesky(k)
        self._alpha = np.stack([linalg.cho_solve((c, True), y[:, i])
                                for i, c in enumerate(self._cholesky)])
        self._prior = (sum(weight for _, weight, *_ in self._side)     # correlations: 1
                       + np.exp(theta[:, -1]))

    def _predict_normalised(self, x: np.ndarray) -> np.ndarray:
        return np.einsum('kmn,kn->mk', cross_covariance(self._side, x), self._alpha)

    def deflection_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                       ) -> np.ndarray:
        """The posterior's standard deviation [m, m, rad], shaped like :meth:`predict`."""
        from scipy import linalg

        x, single = self._inputs(joints, payload)
        normalisation = self._require_fitted()
        cross = cross_covariance(self._side, normalisation.inputs(x))
        explained = np.column_stack([
            (linalg.solve_triangular(c, k.T, lower=True) ** 2).sum(axis=0)
            for c, k in zip(self._cholesky, cross)])
        std = np.sqrt(np.maximum(self._prior - explained, 0.0)) * normalisation.output_std
        return std[0] if single else std

    def position_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                     ) -> np.ndarray | float:
        std = np.asarray(self.deflection_std(joints, payload))
        position = np.hypot(std[..., 0], std[..., 1])
        return float(position) if position.ndim == 0 else position

    def _state(self) -> dict[str, np.ndarray]:
        return {'x': self._x, 'y': self._y, 'theta': self._theta}

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        self._condition(np.asarray(state['x'], dtype=float), np.asarray(state['y'], dtype=float),
                        np.asarray(state['theta'], dtype=float))
