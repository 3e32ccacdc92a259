"""Training of deflection predictors with k-fold cross-validation (pure core of the learner).

:func:`train` checks the data, estimates the error on unseen samples by k-fold
cross-validation (:func:`validate`), then fits the final model on all samples and records the
dataset hash and the metrics in its metadata. Errors are |predicted − measured| deflection
in SI units (m, rad), as ``flexarm_msgs/PredictionMetrics``.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from sklearn.model_selection import KFold

from flexarm_control.dataset import Dataset
from flexarm_control.predictors import Predictor, make_predictor

MIN_SAMPLES = 8


@dataclass(frozen=True)
class Metrics:
    """Validation errors, field for field as ``flexarm_msgs/PredictionMetrics``."""

    validation: str
    samples: int
    max_error_x: float     # [m]
    max_error_y: float     # [m]
    max_error_phi: float   # [rad]
    mean_error_x: float    # [m]
    mean_error_y: float    # [m]
    mean_error_phi: float  # [rad]

    @classmethod
    def from_errors(cls, validation: str, samples: int, errors: np.ndarray) -> Metrics:
        """From absolute errors (M, 3) [m, m, rad]."""
        worst, mean = errors.max(axis=0), errors.mean(axis=0)
        return cls(validation, int(samples), *map(float, worst), *map(float, mean))

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


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


def validate(kind: str, settings: Mapping[str, Any] | None, joints: np.ndarray,
             deflections: np.ndarray, payload: np.ndarray | None = None, folds: int = 5,
             seed: int = 0) -> Metrics:
    """Errors of ``kind`` on held-out samples by ``folds``-fold cross-validation (shuffled)."""
    make_predictor(kind, settings)   # unknown kind or bad settings: fail before any fit
    joints, deflections, payload = check_data(joints, deflections, payload, folds)
    errors = np.empty_like(deflections)
    for train, test in KFold(folds, shuffle=True, random_state=seed).split(joints):
        predictor = make_predictor(kind, settings).fit(
            joints[train], deflections[train], None if payload is None else payload[train])
        predicted = predictor.predict(joints[test], None if payload is None else payload[test])
        errors[test] = np.abs(predicted - deflections[test])
    return Metrics.from_errors(f'{folds}-fold cross-validation', len(joints), errors)


def train(kind: str, settings: Mapping[str, Any] | None, dataset: Dataset, folds: int = 5,
          seed: int = 0) -> tuple[Predictor, Metrics]:
    """Cross-validate, then fit ``kind`` on the whole dataset; hash and metrics in metadata."""
    joints, deflections, payload = dataset.arrays()
    metrics = validate(kind, settings, joints, deflections, payload, folds, seed)
    predictor = make_predictor(kind, settings).fit(joints, deflections, payload)
    predictor.metadata.update(dataset_hash=dataset.hash, metrics=metrics.as_dict())
    return predictor, metrics
