"""Training of deflection predictors: settings chosen by cross-validation, outliers screened,
the model checked for solvability (pure core of the learner).

:func:`train` (on a dataset) and :func:`fit_robust` (on arrays):

1. **Cross-validation** (k-fold, :func:`cross_validate`) of every combination of the kind's
   ``cv_choices`` the caller did not fix (MLP weight decay, GP kernel, RBF smoothing), with
   the kind's cheaper ``cv_overrides`` (GP: 1 restart); the one with the lowest trimmed RMS
   held-out error (the worst 10 % of samples left out, so one bad sample cannot choose) wins.
   Kind ``auto`` (:mod:`~flexarm_control.learning.predictors.auto`) chooses among the candidates of
   every kind of its ``kinds`` at once; the model is an ``AutoPredictor`` of the chosen one.
2. **Outlier screening**: a sample whose held-out residual is ``outlier_threshold`` robust
   standard deviations (1.4826 × median |residual|) off in some output, and more than
   ``outlier_floor`` there, is excluded — the worst one, then the chosen settings are validated
   again without it, at most ``max_outlier_fraction`` of the samples (the choice of step 1
   stands: its trimmed score already ignores a bad sample); excluded samples that the model of
   the kept ones does not contradict are taken back. The floor (1 mm, 2 mrad) is what a real
   sharp feature cannot explain: held-out residuals of good samples reach ~0.5 mm at the edges
   of the sampled region and across the backlash step of joint4. The metrics list the excluded
   samples by their index in the dataset.
3. **Solvability**: the model fitted on the kept samples must change its deflection slower
   than the commanded pose, :func:`~flexarm_control.execution.compensator.deflection_slope` ≤
   ``max_slope`` at every training pose (the true arm: ≤ 0.1); otherwise the next-best choice
   of step 1 is fitted, and if none passes, training fails with the reason.

Errors are |predicted − measured| deflection in SI units (m, rad), as
``flexarm_msgs/PredictionMetrics``, on held-out samples of the kept set. Samples of one pose (a
dataset collected twice with the same seed visits every pose twice) are one group and always
fall on the same side of a fold, so the validation never scores a pose the model was trained
on. :class:`TrainingWorker` runs training jobs in a worker process of their own.
"""
from __future__ import annotations

import itertools
import json
import math
import multiprocessing
import os
import signal
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from flexarm_control.execution.compensator import deflection_slope
from flexarm_control.learning.dataset import Dataset
from flexarm_control.learning.error_bound import calibrate
from flexarm_control.learning.predictors import Predictor, make_predictor
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.parent_death import signal_on_parent_death

MIN_SAMPLES = 8
# [rad, m] Samples whose joints all differ by less than this are one pose, visited again: the
# joints stop within the arrival tolerance (1e-4 rad, 1e-5 m) of the same command; distinct
# learning poses lie millimetres or milliradians apart.
SAME_POSE = 1e-3
TRIM = 0.1          # share of the worst held-out samples the choice of settings ignores
ROBUST_SCALE = 1.4826   # median |residual| × this = standard deviation for a normal error


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


def _subset(payload: np.ndarray | None, index: np.ndarray) -> np.ndarray | None:
    return None if payload is None else payload[index]


def cross_validate(kind: str, settings: Mapping[str, Any] | None, joints: np.ndarray,
                   deflections: np.ndarray, payload: np.ndarray | None = None,
                   folds: int = 5, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Held-out residuals (N, 3), predicted − measured, of ``folds``-fold cross-validation
    (shuffled groups of :func:`pose_groups`: the samples of one pose are held out together),
    and the raw std (N, 3) each fold's model stated for them
    (:meth:`~flexarm_control.learning.predictors.Predictor.deflection_std`). The data must
    have passed :func:`check_data`."""
    from sklearn.model_selection import GroupKFold  # here: the learner node never imports it

    groups = pose_groups(joints)
    if groups.max() + 1 < folds:
        raise ValueError(f'too few distinct poses: {groups.max() + 1} in {len(joints)} '
                         f'samples, at least {folds} are needed ({folds}-fold '
                         'cross-validation)')
    residuals, std = np.empty_like(deflections), np.empty_like(deflections)
    for train_index, test in GroupKFold(folds, shuffle=True, random_state=seed).split(
            joints, groups=groups):
        predictor = make_predictor(kind, settings).fit(
            joints[train_index], deflections[train_index], _subset(payload, train_index))
        residuals[test] = (predictor.predict(joints[test], _subset(payload, test))
                           - deflections[test])
        std[test] = predictor.deflection_std(joints[test], _subset(payload, test))
    return residuals, std


def validate(kind: str, settings: Mapping[str, Any] | None, joints: np.ndarray,
             deflections: np.ndarray, payload: np.ndarray | None = None, folds: int = 5,
             seed: int = 0) -> Metrics:
    """Errors of ``kind`` with fixed ``settings`` on held-out poses (:func:`cross_validate`)."""
    make_predictor(kind, settings)   # unknown kind or bad settings: fail before any fit
    joints, deflections, payload = check_data(joints, deflections, payload, folds)
    residuals, _ = cross_validate(kind, settings, joints, deflections, payload, folds, seed)
    return Metrics.from_errors(f'{folds}-fold cross-validation', len(joints),
                               np.abs(residuals))


def candidates(kind: str, settings: Mapping[str, Any] | None) -> list[dict[str, Any]]:
    """Settings to choose among: every combination of the kind's ``cv_choices`` that
    ``settings`` does not fix, over ``settings``."""
    given = dict(settings or {})
    choices = {name: values for name, values in make_predictor(kind).cv_choices.items()
               if name not in given}
    combos = itertools.product(*choices.values())
    return [{**given, **dict(zip(choices, combo))} for combo in combos]


def _options(kind: str, settings: Mapping[str, Any] | None
             ) -> list[tuple[str, dict[str, Any], dict[str, Any]]]:
    """(kind, settings, the settings given rather than chosen) to choose among: the
    :func:`candidates` of ``kind``, or for ``auto`` those of each of its kinds."""
    if kind != 'auto':
        given = dict(settings or {})
        return [(kind, option, given) for option in candidates(kind, given)]
    auto = make_predictor(kind, settings)
    return [(k, option, auto.kind_settings(k)) for k in auto.settings['kinds']
            for option in candidates(k, auto.kind_settings(k))]


def _trimmed_rms(residuals: np.ndarray, scale: np.ndarray) -> float:
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


def _slope(geometry: ArmGeometry, predictor: Predictor, joints: np.ndarray,
           payload: np.ndarray | None) -> float:
    """The largest :func:`deflection_slope` of ``predictor`` at ``joints`` (N, 4), each at
    its own payload."""
    groups = [(None, joints)] if payload is None else [
        (p, joints[payload == p]) for p in np.unique(payload)]
    return max(float(deflection_slope(
        geometry, lambda q, p=p: predictor.predict(q, p), q).max()) for p, q in groups)


def fit_robust(kind: str, settings: Mapping[str, Any] | None, joints: np.ndarray,
               deflections: np.ndarray, payload: np.ndarray | None = None, folds: int = 5,
               seed: int = 0, geometry: ArmGeometry | None = None,
               screening: Screening = DEFAULT_SCREENING) -> tuple[Predictor, Metrics]:
    """Steps 1-3 of the module docstring on arrays; the fitted predictor and its metrics.

    Screening excludes the worst outlier and validates again until none is left; then the
    model fitted on the kept samples predicts the excluded ones, and those it does not
    contradict (a bad sample's neighbours can look bad while it is in the data) are taken
    back and screened once more. Without ``geometry`` the solvability check is skipped.
    """
    options = _options(kind, settings)
    for option_kind, option, _ in options:
        make_predictor(option_kind, option)   # unknown kind or bad settings: fail before any fit
    joints, deflections, payload = check_data(joints, deflections, payload, folds)
    output_std = deflections.std(axis=0)
    output_std = np.where(output_std > 0, output_std, 1.0)
    kept, excluded = np.arange(len(joints)), np.array([], dtype=int)
    most = int(screening.max_outlier_fraction * len(joints))

    def validate_option(i: int) -> tuple[np.ndarray, np.ndarray]:
        """Held-out residuals and raw stds of option ``i`` on the kept samples."""
        option_kind, option, given = options[i]
        cheaper = {name: value for name, value in make_predictor(option_kind).cv_overrides.items()
                   if name not in given}
        return cross_validate(option_kind, {**option, **cheaper}, joints[kept],
                              deflections[kept], _subset(payload, kept), folds, seed)

    def fit(i: int) -> Predictor:
        option_kind, option, _ = options[i]
        return make_predictor(option_kind, option).fit(joints[kept], deflections[kept],
                                                       _subset(payload, kept))

    def label(i: int) -> dict[str, Any]:
        """The settings option ``i`` chose (and its kind, for ``auto``)."""
        option_kind, option, given = options[i]
        chosen = {name: option[name] for name in option if name not in given}
        return chosen if kind != 'auto' else {'kind': option_kind, **chosen}

    first = [validate_option(i) for i in range(len(options))]
    cv_scores = [_trimmed_rms(residuals, output_std) for residuals, _ in first]
    ranked = sorted(range(len(options)), key=lambda i: cv_scores[i])
    best, (residuals, std) = ranked[0], first[ranked[0]]
    for _ in range(2):          # screen; take back what the screened model does not contradict
        while True:
            scale = ROBUST_SCALE * np.median(np.abs(residuals), axis=0)
            scores = outlier_scores(residuals, scale, screening)
            if not scores.max() > 0 or len(excluded) >= most:
                break
            worst = int(np.argmax(scores))
            excluded, kept = np.append(excluded, kept[worst]), np.delete(kept, worst)
            residuals, std = validate_option(best)
        if not len(excluded):
            break
        predicted = fit(best).predict(joints[excluded], _subset(payload, excluded))
        back = outlier_scores(predicted - deflections[excluded], scale, screening) == 0
        if not back.any():
            break
        kept, excluded = np.sort(np.append(kept, excluded[back])), excluded[~back]
        residuals, std = validate_option(best)
    slopes = []
    for i in ranked:            # the best choice, unless the compensator could not solve with it
        if i != best:
            residuals, std = validate_option(i)
        predictor = fit(i)
        slope = (0.0 if geometry is None else
                 _slope(geometry, predictor, joints[kept], _subset(payload, kept)))
        if slope <= screening.max_slope:
            calibration = calibrate(residuals, std, pose_groups(joints[kept]))
            metrics = Metrics.from_errors(
                f'{folds}-fold cross-validation', len(kept), np.abs(residuals),
                excluded_samples=tuple(int(e) for e in sorted(excluded)),
                selected_settings=json.dumps(label(i)), max_slope=slope,
                bound_coverage=calibration.coverage,
                angle_bound_coverage=calibration.angle_coverage)
            if kind == 'auto':
                by_kind = {k: min(score for (option_kind, _, _), score
                                  in zip(options, cv_scores) if option_kind == k)
                           for k, _, _ in options}
                predictor = make_predictor(kind, settings).adopt(predictor, by_kind)
            predictor.metadata['error_bound'] = calibration.as_dict()
            return predictor, metrics
        slopes.append(f'{json.dumps({**label(i), **options[i][1]})}: {slope:.2f}')
    raise ValueError(
        'every model changes its deflection too fast for the compensator to solve '
        f'(slope > {screening.max_slope} at a training pose; {"; ".join(slopes)}): the data '
        'are too sparse or too noisy — collect more samples')


def train(kind: str, settings: Mapping[str, Any] | None, dataset: Dataset, folds: int = 5,
          seed: int = 0, geometry: ArmGeometry | None = None,
          screening: Screening = DEFAULT_SCREENING) -> tuple[Predictor, Metrics]:
    """:func:`fit_robust` on a dataset; its hash and the metrics go into the metadata."""
    joints, deflections, payload = dataset.arrays()
    predictor, metrics = fit_robust(kind, settings, joints, deflections, payload, folds, seed,
                                    geometry, screening)
    predictor.metadata.update(dataset_hash=dataset.hash, metrics=metrics.as_dict())
    return predictor, metrics


def _worker_start(parent: int, initializer: Callable[[], None] | None) -> None:
    """Worker process start: die with the process that started it (a learner killed with
    SIGKILL would otherwise leave its worker running, reparented to init), then
    ``initializer``."""
    signal_on_parent_death(signal.SIGKILL)
    for sig in (signal.SIGINT, signal.SIGTERM):   # sent to the node's whole process group:
        signal.signal(sig, signal.SIG_IGN)         # the node ends its worker (shutdown)
    if os.getppid() != parent:      # the parent died before the line above
        os._exit(1)
    if initializer is not None:
        initializer()


class TrainingWorker:
    """Runs training jobs one at a time in a worker process (``spawn``) of its own, which dies
    with the process (the thread) that started it.

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
                                   initializer=_worker_start,
                                   initargs=(os.getpid(), self._initializer))

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
        """Drop queued jobs and end the worker process now, also in the middle of a job (its
        result is no longer awaited; a training writes nothing until it has ended). Its
        process is ours alone: SIGKILL, then it is reaped. (``ProcessPoolExecutor`` ends its
        workers only after their jobs before Python 3.14's ``kill_workers``.)"""
        workers = list((getattr(self._pool, '_processes', None) or {}).values())
        for worker in workers:
            worker.kill()
        self._pool.shutdown(wait=True, cancel_futures=True)
