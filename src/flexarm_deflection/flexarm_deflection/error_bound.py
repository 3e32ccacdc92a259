"""A model's 95 % error bound, calibrated on samples it was not fitted on (pure).

Every kind states a raw standard deviation of its prediction
(:meth:`~flexarm_deflection.predictors.Predictor.deflection_std`), but a raw std is
only as right as the kind's assumptions: a GP's posterior, a least-squares covariance or an
ensemble's spread each under- or over-state the miss by a factor of their own. So the learner
scales it on its grouped cross-validation, the one place where it sees the model miss samples
it was not fitted on (normalised split-conformal prediction; Vovk et al., Lei et al. 2018):
score = |held-out residual| / raw std, and the 95 % bound is the score's quantile × raw std.

With 10-40 samples the conformal quantile is coarse: its coverage of new samples varies from
one calibration set to the next (Beta distributed: with 40 samples the 95 % rank covers less
than 0.88 one time in ten). So the rank is the lowest whose coverage falls below 0.93 in at most
one calibration set in ten (:func:`conformal_rank`; the largest score when none is that sure:
below 32 samples), and the scale is the larger of that score and the Gaussian one: the 95 %
point of a normal error (1.96 for the angle; 2.448 / √2 = 1.731 × the radial std for a
position, two normal components) times the scores' RMS, taken at its upper 95 % confidence
limit (χ² with one degree per score and component), so a few lucky folds do not state a bound
the next goal breaks.

The raw std is floored at ``FLOOR_SHARE`` of its median over the held-out samples: a kind
whose raw std is zero (RBF) gets a constant bound, and a point where a posterior is near zero
does not get a near-zero bound. Below 19 held-out samples, where no 95 % conformal quantile
exists and the scale rests on the scores' RMS alone, the bound is at least the plain one too:
the same rule on the residuals themselves (split-conformal without the raw std). There a
model's own std is as unsteady as its fit — the grey-box's 21 parameters on the 8 samples of a
fold leave 3 degrees of freedom to its variance — and with 10 samples the scaled bound alone
covered 70 % of the goals, with the plain one 97 % (benchmarks/uncertainty.py ``samples_10``).
With more samples the plain bound, set by the held-out samples at the region's edges, would
only widen the bound inside it.

What no held-out sample shows is added in quadrature at its own 95 % point:
:meth:`~flexarm_deflection.predictors.Predictor.prior_std` (the grey-box's payload term,
from the masses' prior, when every sample has one payload) here, a refresh's correction
(:func:`correction_bound`, by the predictor), and the site's terms — joint
repeatability, camera noise, the tool calibration's residual — by the planner
(:mod:`flexarm_control.execution.plan_bound`).

``coverage`` (of the position bound) and ``angle_coverage``: measured, not assumed — the
held-out groups split in two halves; one half's scales are checked on the other's samples and
the other way round; the share of samples within their bound.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

LEVEL = 0.95
Z_1D = 1.959964                # 95 % of |e|, e one normal component (an angle, a shift)
Z_2D = 1.730818                # 95 % of |e|, e two equal normal components / |e|'s RMS
FLOOR_SHARE = 0.25             # of the median raw std
TINY = (1e-9, 1e-9)            # [m, rad] floor of a raw std that is zero everywhere
FLOOR_COVERAGE, RISK = 0.93, 0.1   # the calibration's own risk (conformal_rank)


@dataclass(frozen=True)
class BoundCalibration:
    """Scales of a model's raw std into its 95 % bound, from its held-out samples."""

    position_scale: float     # the 95 % position bound / the floored raw position std
    angle_scale: float
    position_floor: float     # [m] the raw position std is at least this
    angle_floor: float        # [rad]
    held_out: int             # samples it was calibrated on
    coverage: float           # of the position bound, on held-out halves (module docstring)
    angle_coverage: float
    position_plain: float = 0.0   # [m] the plain bound: the residuals' own 95 % point
    angle_plain: float = 0.0      # [rad]

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> BoundCalibration:
        return cls(*(float(d[name]) for name in (
            'position_scale', 'angle_scale', 'position_floor', 'angle_floor')),
            int(d['held_out']), float(d['coverage']), float(d['angle_coverage']),
            float(d.get('position_plain', 0.0)), float(d.get('angle_plain', 0.0)))

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def bound(self, std: np.ndarray, prior: np.ndarray | None = None) -> np.ndarray:
        """95 % bounds (..., 2) [m, rad] from raw stds (..., 3) [m, m, rad] and the prior's
        stds (..., 3) of what the held-out samples did not show."""
        position, angle = split(std)
        bound = np.stack([np.maximum(self.position_scale * np.maximum(
            position, self.position_floor), self.position_plain), np.maximum(
            self.angle_scale * np.maximum(angle, self.angle_floor), self.angle_plain)], axis=-1)
        if prior is None:
            return bound
        prior_position, prior_angle = split(prior)
        return np.hypot(bound, np.stack([Z_1D * prior_position, Z_1D * prior_angle],
                                        axis=-1))


def correction_bound(std: np.ndarray) -> np.ndarray:
    """95 % [m, rad] (..., 2) of a refresh's correction error of standard deviations (..., 3)
    [m, m, rad] (its parameters' covariance, :mod:`.drift_correction`): normal, two
    components in position."""
    position, angle = split(std)
    return np.stack([Z_2D * position, Z_1D * angle], axis=-1)


def split(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position (hypot of x and y) and |angle| of (..., 3) [m, m, rad]."""
    values = np.asarray(values, dtype=float)
    return np.hypot(values[..., 0], values[..., 1]), np.abs(values[..., 2])


def conformal_exists(n: int) -> bool:
    """Whether ``n`` held-out samples have a 95 % conformal quantile (n >= 19)."""
    return math.ceil((n + 1) * LEVEL) <= n


def conformal_rank(n: int) -> int:
    """The rank (1-based) of the held-out score that is the bound's scale: the lowest whose
    coverage of new samples (Beta(rank, n + 1 - rank) distributed over calibration sets) falls
    below ``FLOOR_COVERAGE`` in at most ``RISK`` of them; n when none is that sure."""
    from scipy.stats import beta

    return next((k for k in range(math.ceil((n + 1) * LEVEL), n + 1)
                 if beta.ppf(RISK, k, n + 1 - k) >= FLOOR_COVERAGE), n)


def scale(scores: np.ndarray, components: int) -> float:
    """The 95 % scale of normalised scores (n,) (module docstring)."""
    from scipy.stats import chi2

    n = len(scores)
    conformal = float(np.sort(scores)[conformal_rank(n) - 1])
    degrees = components * n
    rms = float(np.sqrt(np.mean(scores ** 2)))
    z = Z_2D if components == 2 else Z_1D
    return max(conformal, z * rms * math.sqrt(degrees / chi2.ppf(1 - LEVEL, degrees)))


def _scales(residuals: np.ndarray, std: np.ndarray, floors: tuple[float, float]
            ) -> tuple[float, float, float, float]:
    """The scales of the raw std (position, angle), then the plain bounds [m, rad]."""
    (error_p, error_a), (std_p, std_a) = split(residuals), split(std)
    return (scale(error_p / np.maximum(std_p, floors[0]), 2),
            scale(error_a / np.maximum(std_a, floors[1]), 1),
            scale(error_p, 2), scale(error_a, 1))


def calibrate(residuals: np.ndarray, std: np.ndarray, groups: np.ndarray | None = None
              ) -> BoundCalibration:
    """The calibration of held-out residuals (n, 3) and the raw stds (n, 3) stated for them
    by models not fitted on them; ``groups`` (n,): samples of one pose, kept on one side of
    the coverage check's halves."""
    residuals, std = np.asarray(residuals, dtype=float), np.asarray(std, dtype=float)
    if residuals.shape != std.shape or residuals.ndim != 2 or len(residuals) < 2:
        raise ValueError(f'residuals and stds of at least 2 samples, each (n, 3), got '
                         f'{residuals.shape} and {std.shape}')
    floors = tuple(max(FLOOR_SHARE * float(np.median(part)), tiny)
                   for part, tiny in zip(split(std), TINY))
    position, angle, position_plain, angle_plain = _scales(residuals, std, floors)
    if conformal_exists(len(residuals)):
        position_plain = angle_plain = 0.0
    return BoundCalibration(position, angle, *floors, len(residuals),
                            *_coverage(residuals, std, floors, groups), position_plain,
                            angle_plain)


def _coverage(residuals: np.ndarray, std: np.ndarray, floors: tuple[float, float],
              groups: np.ndarray | None) -> tuple[float, float]:
    """Shares of samples within the position and the angle bound calibrated on the other
    half of the groups (NaN for fewer than 4 groups)."""
    groups = np.arange(len(residuals)) if groups is None else np.asarray(groups)
    distinct = np.unique(groups)
    if len(distinct) < 4:
        return math.nan, math.nan
    half = np.isin(groups, np.random.default_rng(0).permutation(distinct)[:len(distinct) // 2])
    within = []
    for fit, check in ((half, ~half), (~half, half)):
        position, angle, position_plain, angle_plain = _scales(residuals[fit], std[fit],
                                                               floors)
        if conformal_exists(len(residuals)):
            position_plain = angle_plain = 0.0
        calibration = BoundCalibration(position, angle, *floors, int(fit.sum()), math.nan,
                                       math.nan, position_plain, angle_plain)
        within.append(np.stack(split(residuals[check]), axis=-1)
                      <= calibration.bound(std[check]))
    position, angle = np.concatenate(within).mean(axis=0)
    return float(position), float(angle)
