"""What the physics leaves, learned as each joint's own error: a Gaussian process on
δq_i(q_i) per joint, carried to the instrument by the joint Jacobian.

    residual(q) = Σ_i J_i(q) · δq_i(q_i) + ε,   δq_i ~ GP(0, s_i² · k(q_i, q_i'; ℓ_i)),
    ε ~ N(0, σ² I)

A gear's transmission error, an encoder's eccentricity, a cable's pull: errors that follow one
joint's angle at short scale (on the UR10 of ../shared/data, most of what the physics leaves
follows single joints' angles at length scales of 0.04-0.08 rad). A GP on all joints at
once cannot resolve such a scale from a few hundred rows; one dimension per joint can. Because
δq_i enters through J_i, the model is a GP on the 3-D residual whose covariance between rows
a, b is Σ_i s_i² k_i(a, b) · J_i(a) J_i(b)ᵀ (+ σ² I): exact inference, posterior mean and a
3 × 3 posterior covariance per query.

Kernel k: squared exponential. Hyperparameters (s_i, ℓ_i per joint, σ) by maximum marginal
likelihood (L-BFGS-B on its analytic gradient), from two starting length scales.
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.linalg.lapack import dpotri
from scipy.optimize import minimize

LENGTH_STARTS = (0.1, 1.0)                 # [rad or m] initial ℓ of the two starts
AMPLITUDE_BOUNDS = (1e-8, 1e-2)            # s [rad or m]: 10 mrad is a broken joint
LENGTH_BOUNDS = (5e-3, 1e2)                # ℓ [rad or m]
NOISE_BOUNDS = (1e-7, 1e-2)                # σ [m]
JITTER = 1e-12                             # [m²] on the diagonal
CHUNK = 500                                # query rows per block of a prediction


def _blocks(ja: np.ndarray, jb: np.ndarray) -> np.ndarray:
    """(n, Na, 3, Nb, 3): J_i(a) J_i(b)ᵀ per joint, rows a, b."""
    return np.einsum('aci,bdi->iacbd', ja, jb)


def _distances(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """(n, Na, Nb): squared joint differences per joint."""
    return np.moveaxis((qa[:, None, :] - qb[None, :, :]) ** 2, 2, 0)


class JointErrorGp:
    """The residual GP: fitted on rows of joints, their Jacobians and the residual points."""

    def fit(self, joints: np.ndarray, jacobians: np.ndarray, residual: np.ndarray,
            hyper: np.ndarray | None = None) -> JointErrorGp:
        """``hyper`` (log s, log ℓ, log σ) skips the likelihood's optimisation (a refit on a
        subset, as cross-validation does)."""
        self.joints, self.jacobians = np.asarray(joints, float), np.asarray(jacobians, float)
        y = np.asarray(residual, float).ravel()
        blocks, d2 = _blocks(self.jacobians, self.jacobians), _distances(self.joints,
                                                                           self.joints)
        if hyper is None:
            hyper = self._optimise(blocks, d2, y)
        self.hyper = hyper
        k = self._covariance(hyper, blocks, d2)[0]
        self._factor = cho_factor(k, lower=True)
        self._alpha = cho_solve(self._factor, y)
        return self

    @property
    def noise(self) -> float:
        """σ [m]: what neither the physics nor the joint errors explain, per component."""
        return float(np.exp(self.hyper[-1]))

    def _covariance(self, hyper: np.ndarray, blocks: np.ndarray, d2: np.ndarray):
        """The covariance (3N, 3N), each joint's amplitude² × correlation (n, N, N) and
        the scaled squared distances (n, N, N)."""
        n, rows = blocks.shape[0], blocks.shape[1]
        amp2, length2 = np.exp(2 * hyper[:n]), np.exp(2 * hyper[n:2 * n])
        scaled = d2 / length2[:, None, None]
        corr = amp2[:, None, None] * np.exp(-0.5 * scaled)
        k = np.einsum('iab,iacbd->acbd', corr, blocks).reshape(3 * rows, 3 * rows)
        k[np.diag_indices_from(k)] += np.exp(2 * hyper[-1]) + JITTER
        return k, corr, scaled

    def _optimise(self, blocks: np.ndarray, d2: np.ndarray, y: np.ndarray) -> np.ndarray:
        n = blocks.shape[0]
        bounds = ([tuple(np.log(AMPLITUDE_BOUNDS))] * n + [tuple(np.log(LENGTH_BOUNDS))] * n
                  + [tuple(np.log(NOISE_BOUNDS))])
        noise0 = np.clip(np.std(y) / 2, *NOISE_BOUNDS)
        gain = np.sqrt(np.mean(np.einsum('iacac->ia', blocks), axis=1))
        amp0 = np.clip(np.std(y) / np.maximum(gain, 1e-9) / np.sqrt(n), *AMPLITUDE_BOUNDS)

        def objective(h: np.ndarray) -> tuple[float, np.ndarray]:
            k, corr, scaled = self._covariance(h, blocks, d2)
            try:
                factor = cho_factor(k, lower=True)
            except np.linalg.LinAlgError:
                return 1e25, np.zeros_like(h)
            alpha = cho_solve(factor, y)
            nll = 0.5 * y @ alpha + np.sum(np.log(np.diag(factor[0])))
            inverse, info = dpotri(factor[0], lower=1)
            if info:
                return 1e25, np.zeros_like(h)
            inverse = np.tril(inverse) + np.tril(inverse, -1).T
            inner = np.outer(alpha, alpha) - inverse                    # dL/dK × 2
            rows = len(y) // 3
            weight = np.einsum('acbd,iacbd->iab', inner.reshape(rows, 3, rows, 3), blocks)
            grad = np.empty_like(h)
            grad[:n] = -np.einsum('iab,iab->i', weight, corr)           # d/d log s_i
            grad[n:2 * n] = -0.5 * np.einsum('iab,iab->i', weight, corr * scaled)
            grad[-1] = -np.trace(inner) * np.exp(2 * h[-1])
            return float(nll), grad

        best = None
        for length in LENGTH_STARTS:
            start = np.concatenate([np.log(amp0), np.full(n, np.log(length)), [np.log(noise0)]])
            result = minimize(objective, start, jac=True, method='L-BFGS-B', bounds=bounds)
            if best is None or result.fun < best.fun:
                best = result
        return best.x

    def predict(self, joints: np.ndarray, jacobians: np.ndarray,
                ) -> tuple[np.ndarray, np.ndarray]:
        """Posterior mean (M, 3) [m] and covariance (M, 3, 3) [m²] of the residual at new rows,
        the noise σ² included (what a new measurement scatters by); ``CHUNK`` rows at a time
        (the cross-covariance is 9 N M numbers)."""
        joints, jacobians = np.atleast_2d(joints), np.asarray(jacobians, float)
        parts = [self._predict(joints[k:k + CHUNK], jacobians[k:k + CHUNK])
                 for k in range(0, len(joints), CHUNK)]
        return (np.concatenate([m for m, _ in parts]), np.concatenate([c for _, c in parts]))

    def _predict(self, joints: np.ndarray, jacobians: np.ndarray,
                 ) -> tuple[np.ndarray, np.ndarray]:
        n = jacobians.shape[2]
        amp2, length2 = np.exp(2 * self.hyper[:n]), np.exp(2 * self.hyper[n:2 * n])
        corr = amp2[:, None, None] * np.exp(
            -0.5 * _distances(self.joints, joints) / length2[:, None, None])
        cross = np.einsum('iab,aci,bdi->acbd', corr, self.jacobians, jacobians
                          ).reshape(3 * len(self.joints), 3 * len(joints))
        mean = (cross.T @ self._alpha).reshape(-1, 3)
        v = cho_solve(self._factor, cross)
        prior = np.einsum('i,mci,mdi->mcd', amp2, jacobians, jacobians)
        m = len(joints)
        explained = np.einsum('amc,amd->mcd', cross.reshape(-1, m, 3), v.reshape(-1, m, 3))
        return mean, prior - explained + self.noise ** 2 * np.eye(3)
