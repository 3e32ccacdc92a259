"""Gaussian-process regression of K outputs on shared inputs, each output its own GP: one
kernel form (constant × (RBF, Matérn ν = 5/2 or 3/2, or RBF + a smaller Matérn 3/2 part) with
one length scale per input (ARD) + white noise), hyperparameters by maximum marginal
likelihood with seeded restarts. Inputs and outputs are the caller's (normalised).

In numpy, what scikit-learn's ``GaussianProcessRegressor`` computes (same kernels, bounds,
initial values, seeded restarts, L-BFGS-B on the log marginal likelihood and its analytic
gradient, :func:`negative_log_likelihood`): its kernel objects spent ~1 ms of a likelihood
evaluation handling parameters, 5× the arithmetic for 50 samples, and its prediction ~150 µs
validating the input per output. Nor does a loaded model's query import scikit-learn (~0.5 s).
SciPy is imported where it is used: a node that imports this module to load a model later
starts without it.
"""
from __future__ import annotations

import numpy as np

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


def hyperparameters(kernel: str, scale_bounds: np.ndarray, noise_level: float,
                    noise_bounds: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Initial log-hyperparameters (p,) and their bounds (p, 2) (:func:`_parts`), the length
    scales bounded per input by ``scale_bounds`` (d, 2) and starting at 1 within them."""
    scale_bounds = np.asarray(scale_bounds, float)
    scales = np.maximum(1.0, scale_bounds[:, 0])
    values, limits = [[CONSTANT]], [[CONSTANT_BOUNDS]]
    for j, _ in enumerate(FAMILIES[kernel]):
        if j:
            values.append([PART])
            limits.append([PART_BOUNDS])
        values.append(scales)
        limits.append(scale_bounds)
    values.append([noise_level])
    limits.append([noise_bounds])
    return np.log(np.concatenate(values)), np.log(np.concatenate(limits))


class ArdGp:
    """Independent GPs of the columns of y (N, K) on inputs x (N, d)."""

    def __init__(self, kernel: str = 'rbf') -> None:
        if kernel not in KERNELS:
            raise ValueError(f'kernel must be one of {sorted(KERNELS)}, got {kernel!r}')
        self.kernel = kernel

    def fit(self, x: np.ndarray, y: np.ndarray, theta0: np.ndarray, bounds: np.ndarray,
            restarts: int = 0, seed: int = 0) -> ArdGp:
        """Each output's hyperparameters from ``theta0`` and ``restarts`` starts drawn in the
        bounds as scikit-learn draws them (seed + output), the best likelihood kept."""
        from scipy import optimize

        squares = (x[:, None, :] - x[None, :, :]) ** 2
        theta = []
        for k in range(y.shape[1]):
            rng = np.random.RandomState(seed + k)
            starts = [theta0] + [rng.uniform(bounds[:, 0], bounds[:, 1])
                                 for _ in range(restarts)]
            optima = [optimize.minimize(negative_log_likelihood, start,
                                        (self.kernel, squares, y[:, k]),
                                        method='L-BFGS-B', jac=True, bounds=bounds)
                      for start in starts]
            theta.append(min(optima, key=lambda result: result.fun).x)
        return self.condition(x, y, np.stack(theta))

    def condition(self, x: np.ndarray, y: np.ndarray, theta: np.ndarray) -> ArdGp:
        """The posterior of every output given training data and hyperparameters (K, p)."""
        from scipy import linalg

        self.x, self.y, self.theta = x, y, theta
        self._side = one_side(self.kernel, theta, x)
        k = cross_covariance(self._side, x) + (self.noise + JITTER)[:, None, None] * np.eye(len(x))
        self._cholesky = np.linalg.cholesky(k)
        self._alpha = np.stack([linalg.cho_solve((c, True), y[:, i])
                                for i, c in enumerate(self._cholesky)])
        self._prior = (sum(weight for _, weight, *_ in self._side)     # correlations: 1
                       + self.noise)
        return self

    @property
    def noise(self) -> np.ndarray:
        """(K,): each output's white-noise variance."""
        return np.exp(self.theta[:, -1])

    def mean(self, x: np.ndarray) -> np.ndarray:
        """(M, K): the posterior mean."""
        return np.einsum('kmn,kn->mk', cross_covariance(self._side, x), self._alpha)

    def variance(self, x: np.ndarray) -> np.ndarray:
        """(M, K): the posterior variance of a new measurement (the white noise included)."""
        from scipy import linalg

        cross = cross_covariance(self._side, x)
        explained = np.column_stack([
            (linalg.solve_triangular(c, k.T, lower=True) ** 2).sum(axis=0)
            for c, k in zip(self._cholesky, cross)])
        return np.maximum(self._prior - explained, 0.0)
