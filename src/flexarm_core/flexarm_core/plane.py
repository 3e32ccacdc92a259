"""The arm's plane in 3-D (pure). REP 103: ``base_link`` is z up; the arm moves in its x–z
plane. A planar pose (x, y_up, phi) of the flexarm messages is the point (x, 0, y_up) with the
tool axis turned by phi from +x towards +z: a rotation of phi about −y.

The frame ``arm_plane`` (:mod:`flexarm_core.frames`) is that plane as a frame: ``base_link``
turned +90° about x, so its x, y are the planar x, y_up and its z is −y of ``base_link``, the
axis phi turns about; a planar pose is (x, y_up, 0) turned by phi about z there."""
from __future__ import annotations

import math
from collections.abc import Sequence

PLANE_NORMAL = (0.0, -1.0, 0.0)     # the axis of every revolute joint: +angle turns x to z
PLANE_IN_BASE = (math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5))   # arm_plane in base_link (x,y,z,w)


def position(pose: Sequence[float]) -> tuple[float, float, float]:
    """(x, y_up, ...) -> the point (x, 0, y_up) of base_link [m]."""
    return float(pose[0]), 0.0, float(pose[1])


def orientation(phi: float) -> tuple[float, float, float, float]:
    """The tool angle phi [rad] as a base_link quaternion (x, y, z, w)."""
    return 0.0, -math.sin(phi / 2.0), 0.0, math.cos(phi / 2.0)
