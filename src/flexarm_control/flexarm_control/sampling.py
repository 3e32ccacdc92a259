"""Space-filling learning poses in a working region (pure; scipy.stats.qmc).

A region is a box in task space (x, y, φ). Candidates come from a seeded low-discrepancy
sequence (scrambled Sobol by default, or Halton, Latin hypercube, plain uniform); those the
rigid arm cannot reach inside its joint limits are skipped, so the poses stay space-filling on
the reachable part of the box. Joint positions follow the kinematics' θ2 rule, the same the
compensator uses, so learning samples lie where goals will be executed. Learning poses are
drawn in the region grown by a coverage margin (:meth:`Region.grown`): the compensator
commands x* = x_d − Δ, up to ~25 mm and ~2° outside the box for a target on its edge, and a
model must not extrapolate there. Targets for evaluation (:func:`random_targets`) are uniform
in the box itself, the rigid-reachable ones kept.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_control.kinematics import ArmGeometry, UnreachableError, inverse

STRATEGIES = ('sobol', 'halton', 'lhs', 'random')


@dataclass(frozen=True)
class Region:
    name: str
    lower: np.ndarray   # (3,) x, y [m], φ [rad]
    upper: np.ndarray

    @classmethod
    def from_dict(cls, name: str, d: Mapping[str, Any]) -> Region:
        lower = np.array([d['x'][0], d['y'][0], d['phi'][0]], dtype=float)
        upper = np.array([d['x'][1], d['y'][1], d['phi'][1]], dtype=float)
        if np.any(lower >= upper) or not np.all(np.isfinite(lower + upper)):
            raise ValueError(f'region {name}: each of x, y, phi needs [low, high], low < high')
        return cls(name, lower, upper)

    def grown(self, margin: np.ndarray) -> Region:
        """The box grown by ``margin`` (x, y [m], φ [rad]) on every side."""
        margin = np.asarray(margin, dtype=float)
        return Region(self.name, self.lower - margin, self.upper + margin)

    def describe(self) -> str:
        lo, hi = self.lower, self.upper
        return (f'{self.name}: x {lo[0] * 1e3:.0f}..{hi[0] * 1e3:.0f} mm, y {lo[1] * 1e3:.0f}..'
                f'{hi[1] * 1e3:.0f} mm, phi {math.degrees(lo[2]):.0f}..'
                f'{math.degrees(hi[2]):.0f} deg')


def regions_from_dict(d: Mapping[str, Any]) -> dict[str, Region]:
    return {name: Region.from_dict(name, spec) for name, spec in d.items()}


def unit_samples(strategy: str, count: int, seed: int) -> np.ndarray:
    """``count`` points of the unit cube [0, 1)^3 from ``strategy``."""
    from scipy.stats import qmc  # here: ~0.2 s less for the learner node to start

    if strategy == 'sobol':
        return qmc.Sobol(3, scramble=True, seed=seed).random(count)
    if strategy == 'halton':
        return qmc.Halton(3, scramble=True, seed=seed).random(count)
    if strategy == 'lhs':
        return qmc.LatinHypercube(3, seed=seed).random(count)
    if strategy == 'random':
        return np.random.default_rng(seed).random((count, 3))
    raise ValueError(f'unknown strategy "{strategy}"; choose one of {", ".join(STRATEGIES)}')


def sample_poses(geometry: ArmGeometry, region: Region, count: int, strategy: str = 'sobol',
                 seed: int = 0, max_candidates: int = 65536) -> tuple[np.ndarray, np.ndarray]:
    """``count`` reachable poses (count, 3) of ``region`` and their joints (count, 4).

    Deterministic for (region, count, strategy, seed). Raises ValueError if the region has too
    few reachable poses among ``max_candidates`` candidates.
    """
    if count < 1:
        raise ValueError('count must be at least 1')
    poses, joints = [], []
    batch = 1 << max(4, math.ceil(math.log2(count)) + 1)     # powers of 2 suit Sobol
    while len(poses) < count:
        if batch > max_candidates:
            raise ValueError(f'region {region.name} is mostly out of reach: only '
                             f'{len(poses)} of {count} poses in {max_candidates} candidates')
        poses, joints = [], []
        candidates = region.lower + unit_samples(strategy, batch, seed) * (
            region.upper - region.lower)
        for pose in candidates:
            try:
                joints.append(inverse(geometry, pose))
            except UnreachableError:
                continue
            poses.append(pose)
            if len(poses) == count:
                break
        batch *= 2
    return np.array(poses), np.array(joints)


def random_targets(geometry: ArmGeometry, region: Region, count: int, seed: int
                   ) -> np.ndarray:
    """``count`` targets (count, 3) uniform in ``region``'s box, rigid-reachable ones kept."""
    return sample_poses(geometry, region, count, 'random', seed)[0]


def travel_order(joints: np.ndarray, start: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """Visiting order of ``joints`` (n, 4) from ``start``: greedy nearest neighbour in travel
    time (the slowest joint's |Δq| / speed, joints moving together). Collecting in this order
    instead of the sequence's takes a fraction of the motion time; the set is unchanged."""
    remaining = list(range(len(joints)))
    order, here = [], np.asarray(start, dtype=float)
    while remaining:
        times = np.max(np.abs(joints[remaining] - here) / velocity, axis=1)
        nearest = remaining.pop(int(np.argmin(times)))
        order.append(nearest)
        here = joints[nearest]
    return np.array(order, dtype=int)
