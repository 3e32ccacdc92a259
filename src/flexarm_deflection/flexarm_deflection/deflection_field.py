"""The predicted deflection over a working region (pure): what a model expects the arm to sag
by across the region, for the scene markers and the plots.

The field is sampled on a ``count`` × ``count`` grid of tip positions over the region's x–y box
at its middle tool angle; each grid pose is put at the rigid inverse kinematics' joints (the
arm's redundancy rule) and the model predicts the deflection there. Poses the rigid arm cannot
reach are left out.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from flexarm_core.kinematics import ArmGeometry, UnreachableError, inverse
from flexarm_core.regions import Region


def region_grid(region: Region, count: int) -> np.ndarray:
    """(count², 3) tip poses on the region's x–y box at its middle angle."""
    if count < 1:
        raise ValueError('the field needs count >= 1')
    xs = np.linspace(region.lower[0], region.upper[0], count)
    ys = np.linspace(region.lower[1], region.upper[1], count)
    phi = 0.5 * (region.lower[2] + region.upper[2])
    return np.array([(x, y, phi) for y in ys for x in xs])


def deflection_field(geometry: ArmGeometry, region: Region,
                     predict: Callable[[np.ndarray], np.ndarray], count: int = 7
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(poses (N, 3), predicted deflections (N, 3)) over ``region``; N ≤ count²."""
    poses, joints = [], []
    for pose in region_grid(region, count):
        try:
            joints.append(inverse(geometry, pose))
        except UnreachableError:
            continue
        poses.append(pose)
    if not poses:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return np.array(poses), np.asarray(predict(np.array(joints)), dtype=float).reshape(-1, 3)
