"""Mending a model that no longer fits the arm from a few samples (pure).

When the arm changes after training — a heavier tool nobody declared, thermal growth, a link
bent by a knock — the learned deflection Δ(θ) is off everywhere by something smooth and
low-dimensional. A refresh measures a few samples, then fits a :class:`Correction` added to the
model's prediction: ``Δ'(θ) = Δ(θ) + F(θ) p``, whose columns F are what such changes do to the
tip, linear in small parameters p:

* the joint zeros (4) and the lengths link3, link4 and the lateral offset (3): a bent or
  knocked link, a slipped encoder (the rigid model's sensitivities, :func:`features`);
* growth: every length scaled by (1 + ε), about joint 1 (thermal expansion);
* gravity scale: the model's own deflection scaled by (1 + s) (a different load at the tip).

Nine parameters from as few as five samples (three equations each): a ridge toward zero with
the prior scales ``PRIOR`` keeps them finite, and residuals are weighted by the measurement
noise ``NOISE``. The parameters' covariance (the ridge's posterior, scaled by the residuals'
scatter over the degrees of freedom left where that exceeds ``NOISE``) gives every corrected
prediction its own uncertainty (:meth:`Correction.std`): small near the refresh's samples,
large where the few samples say little, which a bound over the refreshed model needs.
Corrections compose: a refresh of a refreshed model adds another. The model's
training samples are not used again (they describe the arm before the change): the refresh is
incremental, its cost the few samples it measures.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

PARAMETERS = ('joint1_zero', 'joint2_zero', 'joint3_zero', 'joint4_zero', 'link3', 'link4',
              'offset', 'growth', 'gravity_scale')
# Prior scale of each parameter [rad, m, rad, rad, m, m, m, -, -]: a change of about this size
# is as plausible as none.
PRIOR = np.array([2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 5e-4, 0.5])
NOISE = np.array([4e-5, 4e-5, 6e-5])   # [m, m, rad] one averaged measurement of a sample


def features(lengths: tuple[float, float, float], joints: np.ndarray,
             deflection: np.ndarray) -> np.ndarray:
    """F (M, 3, 9): the tip's change per unit of each parameter at joints (M, 4), for the
    arm's (link3, link4, offset) [m] and the model's deflection (M, 3) there."""
    link3, link4, offset = lengths
    q = np.atleast_2d(np.asarray(joints, dtype=float))
    d = np.atleast_2d(np.asarray(deflection, dtype=float))
    t1, t2 = q[:, 0], q[:, 1]
    a13, a134 = t1 + q[:, 2], t1 + q[:, 2] + q[:, 3]
    c1, s1 = np.cos(t1), np.sin(t1)
    x3, y3 = t2 * c1 - offset * s1, t2 * s1 + offset * c1          # joint 3
    x4, y4 = x3 + link3 * np.cos(a13), y3 + link3 * np.sin(a13)    # joint 4
    x, y = x4 + link4 * np.cos(a134), y4 + link4 * np.sin(a134)    # tip
    zero, one = np.zeros_like(t1), np.ones_like(t1)
    columns = [
        (-y, x, one),                           # joint 1 zero: turn about the base
        (c1, s1, zero),                         # joint 2 zero: along the No.2 arm
        (-(y - y3), x - x3, one),               # joint 3 zero: turn about joint 3
        (-(y - y4), x - x4, one),               # joint 4 zero: turn about joint 4
        (np.cos(a13), np.sin(a13), zero),       # link3
        (np.cos(a134), np.sin(a134), zero),     # link4
        (-s1, c1, zero),                        # lateral offset of the No.2 arm
        (x, y, zero),                           # growth about joint 1
        (d[:, 0], d[:, 1], d[:, 2]),            # gravity scale
    ]
    return np.stack([np.stack(c, axis=-1) for c in columns], axis=-1)


@dataclass(frozen=True)
class Correction:
    """``F(θ) p`` on top of a model; ``samples`` measured it, ``residual_*`` [m] are the
    median position residuals of those samples against the model before and after."""

    parameters: np.ndarray                  # (9,) in the order of PARAMETERS
    lengths: tuple[float, float, float]     # [m] link3, link4, offset of the arm's model
    samples: int
    residual_before: float
    residual_after: float
    covariance: np.ndarray = dataclasses.field(
        default_factory=lambda: np.zeros((len(PARAMETERS), len(PARAMETERS))))   # of parameters
    scales: tuple[float, float] = (1.0, 1.0)   # of its position and angle std, held out

    def apply(self, joints: np.ndarray, deflection: np.ndarray) -> np.ndarray:
        """The corrected deflection (M, 3) for the model's ``deflection`` (M, 3) at joints."""
        return deflection + features(self.lengths, joints, deflection) @ self.parameters

    def std(self, joints: np.ndarray, deflection: np.ndarray) -> np.ndarray:
        """(M, 3) [m, m, rad]: the standard deviation of the correction at joints (M, 4),
        for the model's ``deflection`` (M, 3) there, from its parameters' covariance."""
        f = features(self.lengths, joints, deflection)
        std = np.sqrt(np.einsum('mxi,ij,mxj->mx', f, self.covariance, f))
        return std * np.array([self.scales[0], self.scales[0], self.scales[1]])

    def as_dict(self) -> dict[str, Any]:
        return {'parameters': dict(zip(PARAMETERS, self.parameters.tolist())),
                'lengths': list(self.lengths), 'samples': self.samples,
                'residual_before': self.residual_before, 'residual_after': self.residual_after,
                'covariance': self.covariance.tolist(), 'scales': list(self.scales)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Correction:
        """From :meth:`as_dict`; ValueError if incomplete."""
        try:
            values = np.array([float(d['parameters'][name]) for name in PARAMETERS])
            lengths = tuple(float(v) for v in d['lengths'])
            covariance = np.asarray(d.get('covariance', np.zeros((len(PARAMETERS),) * 2)),
                                    dtype=float)    # a file from before covariances: none
            scales = tuple(float(v) for v in d.get('scales', (1.0, 1.0)))
            correction = cls(values, lengths, int(d['samples']), float(d['residual_before']),
                             float(d['residual_after']), covariance, scales)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f'incomplete drift correction {d!r}: {exc}') from exc
        if (len(lengths) != 3 or not np.all(np.isfinite(values))
                or covariance.shape != (len(PARAMETERS),) * 2 or len(scales) != 2):
            raise ValueError(f'invalid drift correction {d!r}')
        return correction


def position_residuals(residuals: np.ndarray) -> np.ndarray:
    """|(dx, dy)| [m] of residuals (M, 3)."""
    return np.hypot(residuals[:, 0], residuals[:, 1])


def left_out(lengths: tuple[float, float, float], joints: np.ndarray, measured: np.ndarray,
             predicted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M, 3) each: every sample's residual under the correction fitted on the others, and the
    standard deviation that correction states there: what a refreshed model leaves, and says it
    leaves, where it was not fitted (leave-one-out)."""
    joints, measured, predicted = (np.atleast_2d(np.asarray(a, dtype=float))
                                   for a in (joints, measured, predicted))
    residuals, std = np.empty_like(measured), np.empty_like(measured)
    for i in range(len(joints)):
        others = np.arange(len(joints)) != i
        p, covariance = _solve(lengths, joints[others], measured[others], predicted[others])
        f = features(lengths, joints[i:i + 1], predicted[i:i + 1])[0]
        residuals[i] = measured[i] - predicted[i] - f @ p
        std[i] = np.sqrt(np.einsum('xi,ij,xj->x', f, covariance, f))
    return residuals, std


def _solve(lengths: tuple[float, float, float], joints: np.ndarray, measured: np.ndarray,
           predicted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The parameters (9,) of the noise-weighted ridge fit and their covariance (9, 9)
    (module docstring)."""
    f = (features(lengths, joints, predicted) / NOISE[None, :, None]).reshape(
        -1, len(PARAMETERS))
    r = ((measured - predicted) / NOISE).reshape(-1)
    a = np.concatenate([f, np.diag(1.0 / PRIOR)])
    p = np.linalg.lstsq(a, np.concatenate([r, np.zeros(len(PARAMETERS))]), rcond=None)[0]
    covariance = np.linalg.pinv(a.T @ a)
    left = len(r) - np.trace(f @ covariance @ f.T)       # degrees of freedom left
    scatter = np.sum((r - f @ p) ** 2) / left if left > 0 else 1.0
    return p, covariance * max(scatter, 1.0)


def fit_correction(lengths: tuple[float, float, float], joints: np.ndarray,
                   measured: np.ndarray, predicted: np.ndarray) -> Correction:
    """The correction that brings ``predicted`` (M, 3) deflections at joints (M, 4) to the
    ``measured`` ones, by noise-weighted ridge least squares (module docstring)."""
    joints = np.atleast_2d(np.asarray(joints, dtype=float))
    measured = np.atleast_2d(np.asarray(measured, dtype=float))
    predicted = np.atleast_2d(np.asarray(predicted, dtype=float))
    if len(joints) < 1 or measured.shape != predicted.shape or measured.shape != (
            len(joints), 3):
        raise ValueError('a correction needs joints (M, 4) and deflections (M, 3), M >= 1')
    p, covariance = _solve(lengths, joints, measured, predicted)
    before = position_residuals(measured - predicted)
    after = position_residuals(measured - predicted - features(lengths, joints, predicted) @ p)
    return Correction(p, tuple(float(v) for v in lengths), len(joints),
                      float(np.median(before)), float(np.median(after)), covariance)
