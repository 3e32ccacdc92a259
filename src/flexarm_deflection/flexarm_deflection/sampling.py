"""Space-filling learning poses in a working region (pure; scipy.stats.qmc).

A region is a box in task space (x, y, φ). Candidates come from a seeded low-discrepancy
sequence (scrambled Sobol by default, or Halton, Latin hypercube, plain uniform); those the
rigid arm cannot reach inside its joint limits are skipped, so the poses stay space-filling on
the reachable part of the box. Joint positions follow the kinematics' θ2 rule, the same the
compensator uses, so learning samples lie where goals will be executed. Learning poses are
drawn in the region grown by a coverage margin (:meth:`Region.grown`): the compensator
commands x* = x_d − Δ, up to ~25 mm and ~2° outside the box for a target on its edge, and a
model must not extrapolate there. Targets for evaluation (:func:`random_targets`) are uniform
in the box itself, the rigid-reachable ones kept. The ``active`` strategy chooses each pose
from the samples taken so far (:mod:`flexarm_deflection.active_sampling`).
:func:`travel_order` orders poses for a short campaign (a path through them in joint-space travel
time).
"""
from __future__ import annotations

import math

import numpy as np

from flexarm_core.kinematics import ArmGeometry, UnreachableError, inverse
from flexarm_core.regions import Region

SPACE_FILLING = ('sobol', 'halton', 'lhs', 'random')
STRATEGIES = (*SPACE_FILLING, 'active')


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
    raise ValueError(f'unknown strategy "{strategy}"; choose one of {", ".join(SPACE_FILLING)}')


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


def travel_times(a: np.ndarray, b: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """[s] from each of ``a`` (n, 4) to each of ``b`` (m, 4), (n, m): the slowest joint's
    |Δq| / speed (joints moving together at their Table 1 speeds)."""
    return np.max(np.abs(a[:, None, :] - b[None, :, :]) / velocity, axis=2)


def path_time(joints: np.ndarray, start: np.ndarray, velocity: np.ndarray) -> float:
    """[s] of travel from ``start`` through ``joints`` (n, 4) in their order."""
    path = np.vstack([np.asarray(start, dtype=float)[None], joints])
    return float(np.sum(np.max(np.abs(np.diff(path, axis=0)) / velocity, axis=1)))


def travel_order(joints: np.ndarray, start: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """Visiting order of ``joints`` (n, 4) from ``start``: a short open path in travel time
    (:func:`travel_times`). Greedy nearest neighbour, then improved by 2-opt (reversing a
    stretch) and or-opt (moving a stretch of 1-3 poses, either way round) until neither
    shortens it; never longer than the greedy path. The set is unchanged. Every move also
    ends with the same short approach leg (:mod:`flexarm_motion.arm_motion`), whatever
    the order, so it does not enter the cost."""
    n = len(joints)
    if n < 2:
        return np.arange(n)
    nodes = np.vstack([np.asarray(start, dtype=float)[None], joints])
    cost = travel_times(nodes, nodes, np.asarray(velocity, dtype=float))
    path = [0]                        # node 0 is the start, fixed; poses are nodes 1..n
    remaining = list(range(1, n + 1))
    while remaining:
        nearest = remaining.pop(int(np.argmin(cost[path[-1], remaining])))
        path.append(nearest)
    improved = True
    while improved:
        improved = _two_opt(path, cost) | _or_opt(path, cost)
    return np.array(path[1:], dtype=int) - 1


def _edge(cost: np.ndarray, path: list[int], i: int) -> float:
    """Cost of the edge from path[i] to path[i + 1] (0 past the open end)."""
    return cost[path[i], path[i + 1]] if i + 1 < len(path) else 0.0


_GAIN = 1e-9        # [s] an improvement smaller than this is rounding, not a shorter path


def _two_opt(path: list[int], cost: np.ndarray) -> bool:
    """Reverse path[i..j] wherever that shortens the path; whether anything changed."""
    changed, n = False, len(path)
    for i in range(1, n - 1):
        a, b = path[i - 1], path[i]
        js = np.arange(i + 1, n)
        tail = np.array(path[i + 1:] + [-1])[1:]          # path[j + 1], -1 past the end
        ends = np.array(path[i + 1:])
        old = cost[a, b] + np.where(tail >= 0, cost[ends, np.maximum(tail, 0)], 0.0)
        new = cost[a, ends] + np.where(tail >= 0, cost[b, np.maximum(tail, 0)], 0.0)
        k = int(np.argmax(old - new))
        if old[k] - new[k] > _GAIN:
            j = int(js[k])
            path[i:j + 1] = path[i:j + 1][::-1]
            changed = True
    return changed


def _or_opt(path: list[int], cost: np.ndarray) -> bool:
    """Move a stretch of 1-3 poses (either way round) to where it shortens the path; whether
    anything changed."""
    changed = False
    for length in (1, 2, 3):
        i = 1
        while i + length <= len(path):
            seg = path[i:i + length]
            rest = path[:i] + path[i + length:]
            inner = sum(cost[seg[k], seg[k + 1]] for k in range(length - 1))
            saving = (cost[rest[i - 1], seg[0]] + inner + _edge(cost, path, i + length - 1)
                      - _edge(cost, rest, i - 1))
            here = np.array(rest)
            after = np.append(here[1:], 0)            # rest[p + 1], 0 as a dummy at the end
            has_next = np.arange(len(rest)) < len(rest) - 1
            best, where, flip = _GAIN, -1, False
            for reverse in (False, True):
                first, last = (seg[-1], seg[0]) if reverse else (seg[0], seg[-1])
                added = cost[here, first] + inner + np.where(
                    has_next, cost[last, after] - cost[here, after], 0.0)
                gain = saving - added
                gain[i - 1] = 0.0                     # back where it was
                k = int(np.argmax(gain))
                if gain[k] > best:
                    best, where, flip = float(gain[k]), k, reverse
            if where >= 0:
                rest[where + 1:where + 1] = seg[::-1] if flip else seg
                path[:] = rest
                changed = True
            else:
                i += 1
    return changed
