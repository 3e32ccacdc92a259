"""Training of deflection models on a dataset (pure core of the learner): :func:`train` makes
the model selection of :func:`~flexarm_deflection.selection.fit_robust` on the dataset's
samples and records its hash and metrics in the model; :func:`validate` scores a kind with
fixed settings on held-out poses; :class:`TrainingWorker` runs training jobs in a worker
process of their own.
"""
from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

import numpy as np

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.parent_death import signal_on_parent_death
from flexarm_deflection.cross_validation import (
    DEFAULT_SCREENING,
    Metrics,
    Screening,
    check_data,
    cross_validate,
)
from flexarm_deflection.dataset import Dataset
from flexarm_deflection.models import make_model
from flexarm_deflection.predictors import Predictor
from flexarm_deflection.selection import fit_robust


def validate(kind: str, settings: Mapping[str, Any] | None, joints: np.ndarray,
             deflections: np.ndarray, payload: np.ndarray | None = None, folds: int = 5,
             seed: int = 0) -> Metrics:
    """Errors of ``kind`` with fixed ``settings`` on held-out poses (:func:`cross_validate`)."""
    make_model(kind, settings)   # unknown kind or bad settings: fail before any fit
    joints, deflections, payload = check_data(joints, deflections, payload, folds)
    residuals, _ = cross_validate(kind, settings, joints, deflections, payload, folds, seed,
                                  make=make_model)
    return Metrics.from_errors(f'{folds}-fold cross-validation', len(joints),
                               np.abs(residuals))


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
