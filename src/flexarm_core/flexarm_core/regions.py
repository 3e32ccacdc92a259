"""The working regions of config/learner.yaml: boxes in task space (x, y, φ) where the arm
learns and is evaluated (pure). Shared: the learner samples them, the compensator's model health
is kept per region, the scene shows them. The nodes get them through their params files; every
other reader takes them from :func:`configured_regions`, so they are defined in one place."""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_core.params import load_config


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


def configured_regions(learner: str = 'flexarm_learner') -> dict[str, Region]:
    """The regions config/learner.yaml gives the learner (and the compensator and the scene),
    the node named ``learner`` in the graph."""
    return regions_from_dict(load_config('learner.yaml', node_name=learner)['regions'])
