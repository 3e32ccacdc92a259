"""What the physics leaves, learned by a Gaussian process on all joints at once: the plain
way (an RBF with one length scale per joint, one GP per axis, white noise), beside the
joint-error GP (:mod:`.joint_error`), which resolves what one joint's own angle does.

Joints and residual are z-scored; each axis' hyperparameters come by maximum marginal
likelihood from the default start and ``RESTARTS`` drawn ones (one start alone often
settles on "all noise" on the UR10 of ../shared/data). Cross-validation refits condition on
the hyperparameters of the fit on all rows, as the joint-error GP's do.
"""
from __future__ import annotations

import numpy as np

from flexarm_learning.ard_gp import ArdGp, hyperparameters

KERNEL = 'rbf'
LENGTH_BOUNDS = (1e-2, 1e3)       # in z-scored joints
NOISE, NOISE_BOUNDS = 1e-2, (1e-6, 1.0)    # variance, in z-scored residual
RESTARTS = 2


class ResidualGp:
    """The GP, fitted on rows of joints (N, n) and residual points (N, 3) [m]."""

    def fit(self, joints: np.ndarray, residual: np.ndarray, theta: np.ndarray | None = None,
            seed: int = 0) -> ResidualGp:
        """``theta`` (3, p) skips the likelihood's optimisation (a refit on a subset)."""
        self._mean, self._std = joints.mean(axis=0), joints.std(axis=0) + 1e-12
        self._out_mean, self._out_std = residual.mean(axis=0), residual.std(axis=0) + 1e-12
        x = (joints - self._mean) / self._std
        y = (residual - self._out_mean) / self._out_std
        gp = ArdGp(KERNEL)
        if theta is None:
            start, bounds = hyperparameters(KERNEL, np.tile(LENGTH_BOUNDS, (x.shape[1], 1)),
                                            NOISE, NOISE_BOUNDS)
            self.gp = gp.fit(x, y, start, bounds, RESTARTS, seed)
        else:
            self.gp = gp.condition(x, y, theta)
        return self

    @property
    def theta(self) -> np.ndarray:
        return self.gp.theta

    def predict(self, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean (M, 3) [m] and covariance (M, 3, 3) [m²], the noise included."""
        x = (np.atleast_2d(joints) - self._mean) / self._std
        variance = self.gp.variance(x) * self._out_std ** 2
        return (self.gp.mean(x) * self._out_std + self._out_mean,
                variance[:, :, None] * np.eye(3))
