"""Training of deflection predictors with k-fold cross-validation (pure core of the learner).

:func:`train` checks the data, estimates the error on unseen samples by k-fold
cross-validation (:func:`validate`), then fits the final model on all samples and records the
dataset hash and the metrics in its metadata. Errors are |predicted − measured| deflection
in SI units (m, rad), as ``flexarm_msgs/PredictionMetrics``. Samples of one pose (a dataset
collected twice with the same seed visits every pose twice) are one group and always fall on
the same side of a fold, so the validation never scores a pose the model was trained on.
:class:`TrainingWorker` runs training jobs in a worker process of their own.
"""
from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from sklearn.model_selection import GroupKFold

from flexarm_control.dataset import Dataset
from flexarm_control.predictors import Predictor, make_predictor

MIN_SAMPLES = 8
# [rad, m] Samples whose joints all differ by less than this are one pose, visited again: the
# joints stop within the arrival tolerance (1e-4 rad, 1e-5 m) of the same command; distinct
# learning poses lie millimetres or milliradians apart.
SAME_POSE = 1e-3


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


def pose_groups(joints: np.ndarray) -> np.ndarray:
    """Group label (N,) per sample: samples linked by joints all within ``SAME_POSE`` of each
    other share one."""
    pairs = cKDTree(joints).query_pairs(SAME_POSE, p=np.inf, output_type='ndarray')
    links = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                       shape=(len(joints), len(joints)))
    return connected_components(links, directed=False)[1]


def validate(kind: str, settings: Mapping[str, Any] | None, joints: np.ndarray,
             deflections: np.ndarray, payload: np.ndarray | None = None, folds: int = 5,
             seed: int = 0) -> Metrics:
    """Errors of ``kind`` on held-out poses by ``folds``-fold cross-validation (shuffled
    groups of :func:`pose_groups`: the samples of one pose are held out together)."""
    make_predictor(kind, settings)   # unknown kind or bad settings: fail before any fit
    joints, deflections, payload = check_data(joints, deflections, payload, folds)
    groups = pose_groups(joints)
    if groups.max() + 1 < folds:
        raise ValueError(f'too few distinct poses: {groups.max() + 1} in {len(joints)} '
                         f'samples, at least {folds} are needed ({folds}-fold '
                         'cross-validation)')
    errors = np.empty_like(deflections)
    for train, test in GroupKFold(folds, shuffle=True, random_state=seed).split(
            joints, groups=groups):
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


class TrainingWorker:
    """Runs training jobs one at a time in a worker process (``spawn``) of its own.

    A job that outlives its timeout cannot be stopped: it keeps the worker until it ends and
    :meth:`run` refuses new jobs until then. A worker that died (killed, out of memory) is
    replaced by a new one; the job it ran fails.
    """

    def __init__(self, initializer: Callable[[], None] | None = None) -> None:
        self._initializer = initializer
        self._pool = self._start()
        self._job: Future | None = None

    def _start(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context('spawn'),
                                   initializer=self._initializer)

    def run(self, job: Callable[..., Any], *args: Any, timeout: float) -> Any:
        """``job(*args)`` in the worker; its result, or its exception re-raised here.

        TimeoutError after ``timeout`` s [wall]; RuntimeError when the worker is still busy
        with a job that timed out, or died.
        """
        if self._job is not None and not self._job.done():
            raise RuntimeError('busy: an earlier job that timed out still runs in the worker '
                               'process; try again when it has ended')
        try:
            self._job = self._pool.submit(job, *args)
            return self._job.result(timeout=timeout)
        except BrokenProcessPool as exc:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = self._start()
            raise RuntimeError(f'the worker process died ({exc}); a new one is started, '
                               'try again') from exc
        except TimeoutError as exc:
            raise TimeoutError(f'no result after {timeout:.0f} s; the job keeps running in the '
                               'worker process and new jobs are refused until it ends') from exc

    def shutdown(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)
