"""Cross-validation of deflection models on poses they were not trained on, and the screening
of samples it flags (pure core of the learner's training).

Errors are |predicted − measured| deflection in SI units (m, rad), as
``flexarm_msgs/PredictionMetrics``. Samples of one pose (a dataset collected twice with the
same seed visits every pose twice) are one group and always fall on the same side of a fold,
so the validation never scores a pose the model was trained on. A sample is an outlier when
its held-out residual is ``outlier_threshold`` robust standard deviations (1.4826 × median
|residual|) off in some output and more than ``outlier_floor`` there (:class:`Screening`).
"""
from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from flexarm_deflection.predictors import Predictor, make_predictor

MIN_SAMPLES = 8
# [rad, m] Samples whose joints all differ by less than this are one pose, visited again: the
# joints stop within the arrival tolerance (1e-4 rad, 1e-5 m) of the same command; distinct
# learning poses lie millimetres or milliradians apart.
SAME_POSE = 1e-3
TRIM = 0.1          # share of the worst held-out samples the choice of settings ignores
ROBUST_SCALE = 1.4826   # median |residual| × this = standard deviation for a normal error


Make = Callable[[str, Mapping[str, Any] | None], Predictor]


@dataclass(frozen=True)
class Screening:
    """Outlier screening and solvability check (config/learner.yaml ``training.*``)."""

    outlier_threshold: float = 6.0     # robust standard deviations of a held-out residual
    outlier_floor: tuple[float, float, float] = (1e-3, 1e-3, 2e-3)   # [m, m, rad]
    max_outlier_fraction: float = 0.1  # of the samples
    max_slope: float = 0.5             # of the deflection against the commanded pose

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Screening:
        s = cls(float(d['outlier_threshold']), tuple(float(v) for v in d['outlier_floor']),
                float(d['max_outlier_fraction']), float(d['max_slope']))
        if (s.outlier_threshold <= 0 or len(s.outlier_floor) != 3 or min(s.outlier_floor) < 0
                or not 0 <= s.max_outlier_fraction < 0.5 or s.max_slope <= 0):
            raise ValueError(f'invalid training screening settings {s}')
        return s


DEFAULT_SCREENING = Screening()
NO_SCREENING = Screening(max_outlier_fraction=0.0)   # excludes no sample


@dataclass(frozen=True)
class Metrics:
    """Validation errors and what training decided, field for field as
    ``flexarm_msgs/PredictionMetrics``."""

    validation: str
    samples: int
    max_error_x: float     # [m]
    max_error_y: float     # [m]
    max_error_phi: float   # [rad]
    mean_error_x: float    # [m]
    mean_error_y: float    # [m]
    mean_error_phi: float  # [rad]
    excluded_samples: tuple[int, ...] = ()   # dataset indices screened out as outliers
    selected_settings: str = ''              # JSON of the settings chosen by validation
    max_slope: float = 0.0                   # of the final model over the training poses
    bound_coverage: float = math.nan         # of the 95 % bounds on held-out halves
    angle_bound_coverage: float = math.nan   #   (learning.error_bound)

    @classmethod
    def from_errors(cls, validation: str, samples: int, errors: np.ndarray,
                    **decisions: Any) -> Metrics:
        """From absolute errors (M, 3) [m, m, rad]."""
        worst, mean = errors.max(axis=0), errors.mean(axis=0)
        return cls(validation, int(samples), *map(float, worst), *map(float, mean),
                   **decisions)

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d['excluded_samples'] = list(self.excluded_samples)
        return d


def check_data(joints: np.ndarray, deflections: np.ndarray, payload: np.ndarray | None,
               folds: int) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The data as float arrays; ValueError with the reason if it cannot be trained on."""
    joints = np.asarray(joints, dtype=float)
    deflections = np.asarray(deflections, dtype=float)
    if joints.ndim != 2 or joints.shape[1] != 4:
        raise ValueError(f'joints must have shape (N, 4), got {joints.shape}')
    if deflections.shape != (len(joints), 3):
        raise ValueError(f'deflections must have shape ({len(joints)}, 3), '
                         f'got {deflections.shape}')
    if payload is not None:
        payload = np.asarray(payload, dtype=float)
        if payload.shape != (len(joints),):
            raise ValueError(f'payload must have shape ({len(joints)},), got {payload.shape}')
    if folds < 2:
        raise ValueError(f'cross-validation needs at least 2 folds, got {folds}')
    needed = max(MIN_SAMPLES, folds + 1)
    if len(joints) < needed:
        raise ValueError(f'too few samples: {len(joints)}, at least {needed} are needed '
                         f'({folds}-fold cross-validation)')
    for name, values in (('joints', joints), ('deflections', deflections),
                         ('payload', payload)):
        if values is not None and not np.all(np.isfinite(values)):
            bad = int(np.count_nonzero(~np.isfinite(values).reshape(len(joints), -1).all(1)))
            raise ValueError(f'{name} contain NaN or infinite values in {bad} samples')
    return joints, deflections, payload


def pose_groups(joints: np.ndarray) -> np.ndarray:
    """Group label (N,) per sample: samples linked by joints all within ``SAME_POSE`` of each
    other share one."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pairs = cKDTree(joints).query_pairs(SAME_POSE, p=np.inf, output_type='ndarray')
    links = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                       shape=(len(joints), len(joints)))
    return connected_components(links, directed=False)[1]


def subset(payload: np.ndarray | None, index: np.ndarray) -> np.ndarray | None:
    return None if payload is None else payload[index]


def grouped_folds(groups: np.ndarray, folds: int, seed: int) -> list[np.ndarray]:
    """The held-out indices of each fold: the distinct groups in a seeded random order, split
    into ``folds`` runs of near-equal count (scikit-learn's ``GroupKFold(shuffle=True)``, the
    same folds for the same seed, without importing scikit-learn for it)."""
    order = np.random.RandomState(seed).permutation(np.unique(groups))
    return [np.flatnonzero(np.isin(groups, part)) for part in np.array_split(order, folds)]


def cross_validate(kind: str, settings: Mapping[str, Any] | None, joints: np.ndarray,
                   deflections: np.ndarray, payload: np.ndarray | None = None,
                   folds: int = 5, seed: int = 0, make: Make = make_predictor,
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Held-out residuals (N, 3), predicted − measured, of ``folds``-fold cross-validation
    (shuffled groups of :func:`pose_groups`: the samples of one pose are held out together),
    and the raw std (N, 3) each fold's model stated for them
    (:meth:`~flexarm_deflection.predictors.Predictor.deflection_std`). The data must
    have passed :func:`check_data`. ``make`` builds the models (default: the predictors; a
    model that selects among them is validated through its own maker)."""
    groups = pose_groups(joints)
    if groups.max() + 1 < folds:
        raise ValueError(f'too few distinct poses: {groups.max() + 1} in {len(joints)} '
                         f'samples, at least {folds} are needed ({folds}-fold '
                         'cross-validation)')
    residuals, std = np.empty_like(deflections), np.empty_like(deflections)
    for test in grouped_folds(groups, folds, seed):
        train_index = np.setdiff1d(np.arange(len(joints)), test)
        predictor = make(kind, settings).fit(
            joints[train_index], deflections[train_index], subset(payload, train_index))
        residuals[test] = (predictor.predict(joints[test], subset(payload, test))
                           - deflections[test])
        std[test] = predictor.deflection_std(joints[test], subset(payload, test))
    return residuals, std


def candidates(kind: str, settings: Mapping[str, Any] | None) -> list[dict[str, Any]]:
    """Settings to choose among: every combination of the kind's ``cv_choices`` that
    ``settings`` does not fix, over ``settings``."""
    given = dict(settings or {})
    choices = {name: values for name, values in make_predictor(kind).cv_choices.items()
               if name not in given}
    combos = itertools.product(*choices.values())
    return [{**given, **dict(zip(choices, combo))} for combo in combos]


def trimmed_rms(residuals: np.ndarray, scale: np.ndarray) -> float:
    """RMS of the per-sample residual norms (outputs divided by ``scale``), the worst
    ``TRIM`` of the samples left out."""
    norms = np.sort(np.linalg.norm(residuals / scale, axis=1))
    return float(np.sqrt(np.mean(norms[:max(1, round(len(norms) * (1 - TRIM)))] ** 2)))


def outlier_scores(residuals: np.ndarray, scale: np.ndarray, screening: Screening
                   ) -> np.ndarray:
    """Per sample (N,): the largest robust z (|residual| / ``scale``) among its outputs that
    are outliers — beyond ``outlier_threshold`` and ``outlier_floor`` — else 0."""
    z = np.abs(residuals) / np.where(scale > 0, scale, np.inf)
    flagged = (z > screening.outlier_threshold) & (
        np.abs(residuals) > np.asarray(screening.outlier_floor))
    return np.where(flagged, z, 0.0).max(axis=1)
