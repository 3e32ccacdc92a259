"""Does the model still fit the arm? Watched from every measured goal (pure).

Every measurement the compensator takes (any mode, every move of a goal, whenever the camera
sees the plate) is a free check of the model: the measured deflection (measured tip − rigid
model at the reported joints) against the model's prediction there. Each residual is filed
under the first working region whose box holds the measured pose (config/learner.yaml order;
``elsewhere`` if none). A region's statistic is the median position residual of its last
``window`` observations (the median: one bad frame does not decide); the region turns *stale*
once it has ``min_observations`` and the median exceeds ``stale_residual``. The compensator
publishes the result, warns in goal results and logs; a refresh
(:mod:`flexarm_deflection.drift_correction`) measures where the worst residuals were
(:meth:`ModelHealth.worst_joints`). A new model starts with a clean record.

A healthy model's residual is its prediction error plus the measurement's noise: in the
realistic world the median is 0.03-0.06 mm (PREDICTIVE p95 0.12 mm, benchmarks/error_budget.py);
``stale_residual`` (0.15 mm by default) sits well above that and below the 0.3 mm a refreshed
model must reach.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_core.regions import Region

ELSEWHERE = 'elsewhere'


@dataclass(frozen=True)
class HealthSettings:
    window: int = 8                 # observations per region the statistic looks at
    min_observations: int = 3       # before a region can turn stale
    stale_residual: float = 1.5e-4  # [m] median position residual that marks a region stale

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> HealthSettings:
        s = cls(int(d['window']), int(d['min_observations']), float(d['stale_residual']))
        if not 1 <= s.min_observations <= s.window or not s.stale_residual > 0:
            raise ValueError(f'model health: 1 <= min_observations <= window, '
                             f'stale_residual > 0; got {s}')
        return s


@dataclass(frozen=True)
class Observation:
    joints: np.ndarray      # (4,) reported at the measurement
    residual: np.ndarray    # (3,) measured − predicted deflection [m, m, rad]

    @property
    def position(self) -> float:
        return float(np.hypot(self.residual[0], self.residual[1]))


@dataclass(frozen=True)
class RegionHealth:
    name: str
    observations: int
    median_position: float   # [m]
    max_position: float      # [m]
    median_angle: float      # [rad]
    stale: bool


class ModelHealth:
    """Residual statistics of one model per working region (module docstring)."""

    def __init__(self, settings: HealthSettings, regions: Mapping[str, Region]) -> None:
        self.settings = settings
        self.regions = dict(regions)
        self.version = ''
        self._seen: dict[str, deque[Observation]] = {}

    def reset(self, version: str) -> None:
        """A new model: forget every observation."""
        self.version = version
        self._seen.clear()

    def region_of(self, pose: np.ndarray) -> str:
        for name, region in self.regions.items():
            if np.all(region.lower <= pose) and np.all(pose <= region.upper):
                return name
        return ELSEWHERE

    def observe(self, pose: np.ndarray, joints: np.ndarray, residual: np.ndarray) -> str:
        """File the residual (3,) measured at ``pose`` (3,) with ``joints`` (4,); its region."""
        name = self.region_of(np.asarray(pose, dtype=float))
        seen = self._seen.setdefault(name, deque(maxlen=self.settings.window))
        seen.append(Observation(np.asarray(joints, dtype=float).copy(),
                                np.asarray(residual, dtype=float).copy()))
        return name

    def report(self) -> list[RegionHealth]:
        """Every region observed so far, in the order first observed."""
        out = []
        for name, seen in self._seen.items():
            position = np.array([o.position for o in seen])
            angle = np.array([abs(o.residual[2]) for o in seen])
            median = float(np.median(position))
            out.append(RegionHealth(
                name, len(seen), median, float(position.max()), float(np.median(angle)),
                len(seen) >= self.settings.min_observations
                and median > self.settings.stale_residual))
        return out

    def stale_regions(self) -> list[str]:
        return [r.name for r in self.report() if r.stale]

    def worst_joints(self, region: str, count: int) -> np.ndarray:
        """Joints (≤ count, 4) of the region's largest position residuals, largest first."""
        seen = sorted(self._seen.get(region, ()), key=lambda o: -o.position)
        return np.array([o.joints for o in seen[:count]]).reshape(-1, 4)

    def summary(self, region: str | None = None) -> str:
        """One line for logs and goal results: the stale regions, or only ``region`` if given
        (a goal's result speaks of where the goal went); '' if none."""
        stale = [r for r in self.report() if r.stale and region in (None, r.name)]
        return '; '.join(
            f'model {self.version} is stale in region {r.name}: median residual '
            f'{r.median_position * 1e3:.3f} mm over the last {r.observations} measurements '
            f'(> {self.settings.stale_residual * 1e3:.3f} mm): refresh it (`flexarm refresh`) '
            'or collect and train anew' for r in stale)
