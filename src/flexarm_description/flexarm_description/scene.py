"""What the scene markers draw, as 3-D points in base_link (pure; see :mod:`.scene_node`).

Regions are outlined in the arm's plane; a deflection is an arrow from the rigid tip position
to the rigid one plus the deflection × ``scale`` (deflections are millimetres on a 1.5 m arm:
drawn true to size they would not be seen).
"""
from __future__ import annotations

import numpy as np

from flexarm_core import plane
from flexarm_core.regions import Region


def region_outline(region: Region) -> np.ndarray:
    """(5, 3) closed outline of the region's x–y box in the arm's plane."""
    (x0, y0), (x1, y1) = region.lower[:2], region.upper[:2]
    return np.array([plane.position(p) for p in
                     ((x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0))])


def region_label(region: Region) -> tuple[np.ndarray, str]:
    """Where the region's name goes (above its top edge) and the text."""
    x = 0.5 * (region.lower[0] + region.upper[0])
    return np.array(plane.position((x, region.upper[1] + 0.03))), f'region {region.name}'


def deflection_arrows(poses: np.ndarray, deflections: np.ndarray, scale: float
                      ) -> list[tuple[np.ndarray, np.ndarray]]:
    """(start, end) 3-D points of one arrow per pose: rigid tip -> + deflection × scale."""
    ends = poses[:, :2] + deflections[:, :2] * scale
    return [(np.array(plane.position(p)), np.array(plane.position(e)))
            for p, e in zip(poses, ends, strict=True)]


def sample_points(measured: np.ndarray) -> np.ndarray:
    """(N, 3) base_link points of measured planar tip poses (N, ≥2)."""
    return np.array([plane.position(p) for p in measured]).reshape(-1, 3)
