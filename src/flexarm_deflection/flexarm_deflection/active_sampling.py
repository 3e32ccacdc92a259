"""Active choice of learning poses: each next pose where the model so far is least sure (pure).

The ``active`` collection strategy (:data:`flexarm_deflection.sampling.STRATEGIES`).
Candidates are ``pool`` reachable poses of the region grown by the coverage margin (scrambled
Sobol, seeded; joints by the kinematics' θ2 rule, as
:func:`~flexarm_deflection.sampling.sample_poses`). The first ``initial`` of them —
space-filling — are visited in a short-travel order
(:func:`~flexarm_deflection.sampling.travel_order`); from then on every pose is the
candidate with the largest predictive standard deviation of the tip position
(:meth:`~flexarm_deflection.predictors.base.Predictor.position_std`) of a Gaussian process
(:mod:`flexarm_deflection.predictors.gp`, one cheap fit: RBF kernel, no restarts) on the
samples stored so far.

Pipelined so the arm does not wait for the fit: the pose after the one being visited is
chosen while the arm moves to it and measures, from the samples stored until then plus the
pose under way with the model's own prediction as its deflection ("kriging believer": a GP's
standard deviation depends on where the data are, not on their values). ``run`` executes a
choice (:func:`choose`): the learner hands it to a thread that waits on its training worker
process; offline it runs at once. A choice that is not ready when the arm needs its next pose
(the worker process still starting) is not waited for: the next space-filling candidate is
taken instead and the choice used afterwards.

Travel: the most uncertain candidates lie far apart (edges and corners of the region), so
among the candidates within ``near_best`` of the largest standard deviation the one nearest
in travel time is taken. Measured (benchmarks/sample_efficiency.py, realistic world, GP, 3
seeds, 20-sample campaigns; the worst seed's samples to < 1 mm max error in A / B, travel
per sample at the Table 1 speeds): near_best 1.0: 12 / 12, 2.85 s; 0.75: 15 / 12, 2.22 s;
0.5: 12 / 15, 1.58 s; 0.3: 20 / 20, 1.29 s (sobol in travel order: 0.85 s in A, 1.15 s in
B). Deterministic for (region, count, seed, settings) and the samples measured, when every
choice comes in time (offline: always).
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.regions import Region
from flexarm_deflection.predictors import make_predictor
from flexarm_deflection.sampling import sample_poses, travel_order, travel_times

Samples = Callable[[], tuple[np.ndarray, np.ndarray]]   # joints (n, 4), deflections (n, 3)
Runner = Callable[..., 'Future[int]']                     # run(choose, *args) -> its future


@dataclass(frozen=True)
class ActiveSettings:
    initial: int = 6            # space-filling poses before the first model
    pool: int = 256             # candidate poses
    near_best: float = 0.5      # candidates with std >= this x the largest are near enough
    model: tuple[tuple[str, Any], ...] = (('kernel', 'rbf'), ('restarts', 0))  # GP settings

    def __post_init__(self) -> None:
        if self.initial < 2 or self.pool < self.initial or not 0 < self.near_best <= 1:
            raise ValueError('active sampling needs initial >= 2, pool >= initial and '
                             f'0 < near_best <= 1, got {self}')


def choose(candidates: np.ndarray, free: np.ndarray, joints: np.ndarray,
           deflections: np.ndarray, pending: np.ndarray, here: np.ndarray,
           velocity: np.ndarray, settings: ActiveSettings, seed: int) -> int:
    """Index into ``candidates`` (m, 4) of the next pose among the ``free`` ones (bool (m,)):
    the largest position std of a GP on the measured ``joints`` (n, 4) / ``deflections``
    (n, 3) and the ``pending`` poses (k, 4) at their predicted deflection; of those within
    ``near_best`` of it, the nearest in travel time from ``here`` (4,)."""
    model = dict(settings.model, seed=seed)
    gp = make_predictor('gp', model).fit(joints, deflections)
    if len(pending):
        gp = make_predictor('gp', model).fit(np.vstack([joints, pending]),
                                             np.vstack([deflections, gp.predict(pending)]))
    index = np.flatnonzero(free)
    std = np.asarray(gp.position_std(candidates[index]))
    near = index[std >= settings.near_best * std.max()]
    travel = travel_times(here[None], candidates[near], velocity)[0]
    return int(near[np.argmin(travel)])


def run_now(job: Callable[..., int], *args: Any) -> Future[int]:
    """``job(*args)`` here and now, as a finished future."""
    future: Future[int] = Future()
    future.set_result(job(*args))
    return future


DEFAULT_SETTINGS = ActiveSettings()


class ActivePoses:
    """The joints (4,) of ``count`` learning poses, each chosen from the samples before it.

    Iterate once, as :meth:`~flexarm_control.execution.collection.Collector.collect` does: the
    next pose is asked for after the sample of the one before was stored (or skipped), and
    ``samples()`` gives every sample stored so far.
    """

    def __init__(self, geometry: ArmGeometry, region: Region, count: int, seed: int,
                 samples: Samples, start: np.ndarray, run: Runner = run_now,
                 settings: ActiveSettings = DEFAULT_SETTINGS) -> None:
        if count < 1:
            raise ValueError('count must be at least 1')
        self.geometry, self.count, self.seed = geometry, count, seed
        self.samples, self.start, self.run, self.settings = samples, start, run, settings
        _, self.candidates = sample_poses(geometry, region, max(settings.pool, count), 'sobol',
                                          seed)

    def __iter__(self) -> Iterator[np.ndarray]:
        free = np.ones(len(self.candidates), dtype=bool)
        first = min(self.settings.initial, self.count)
        order = travel_order(self.candidates[:first], self.start, self.geometry.velocity)
        free[order] = False
        yield from self.candidates[order[:-1]]
        chosen = int(order[-1])
        future: Future[int] | None = None
        for k in range(first, self.count + 1):
            if k < self.count and future is None:   # chosen while the arm goes to ``chosen``
                future = self._next(free, self.candidates[chosen])
            yield self.candidates[chosen]
            if k == self.count or future is None:
                break
            if future.done():
                chosen, future = future.result(), None
            if not free[chosen]:    # not chosen in time (or taken meanwhile): no waiting
                chosen = int(np.flatnonzero(free)[0])
            free[chosen] = False

    def _next(self, free: np.ndarray, pending: np.ndarray) -> Future[int]:
        """The choice after ``pending``, the pose under way (the next space-filling candidate
        while fewer than 2 samples are stored)."""
        joints, deflections = self.samples()
        if len(joints) < 2:
            return run_now(lambda: int(np.flatnonzero(free)[0]))
        return self.run(choose, self.candidates, free.copy(), np.asarray(joints),
                        np.asarray(deflections), pending[None], pending,
                        self.geometry.velocity, self.settings, self.seed)
