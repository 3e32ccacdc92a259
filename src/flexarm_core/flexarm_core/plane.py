"""The arm's plane in 3-D (pure). REP 103: ``base_link`` is z up; the arm moves in its x–z
plane. A planar pose (x, y_up, phi) of the flexarm messages is the point (x, 0, y_up) with the
tool axis turned by phi from +x towards +z: a rotation of phi about −y."""
from __future__ import annotations

import math
from collections.abc import Sequence

PLANE_NORMAL = (0.0, -1.0, 0.0)     # the axis of every revolute joint: +angle turns x to z


def position(pose: Sequence[float]) -> tuple[float, float, float]:
    """(x, y_up, ...) -> the point (x, 0, y_up) of base_link [m]."""
    return float(pose[0]), 0.0, float(pose[1])


def orientation(phi: float) -> tuple[float, float, float, float]:
    """The tool angle phi [rad] as a base_link quaternion (x, y, z, w)."""
    return 0.0, -math.sin(phi / 2.0), 0.0, math.cos(phi / 2.0)
