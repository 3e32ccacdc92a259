"""Tip camera geometry: plate coordinates <-> pixels for a tip pose (pure, shared by the
simulated camera and the pose estimator).

The camera looks perpendicularly at the plate (the base x-y plane) from the arm's side, from a
fixed standoff. Its optical axis meets the plate at ``c = t + R(phi) offset``, where ``t`` is
the tip position, ``phi`` the tool angle and ``offset`` the camera-to-tip offset in the tip
frame. The image u axis is the tool axis (tip-frame x), the image v axis points along the
tip-frame -y (image rows grow downwards, plate y grows upwards), so the view is not mirrored.
Pixel centres are at integer coordinates; (cx, cy) is the principal point.

Per-point mapping, with ``q = R(phi)^T (p - c)`` the plate point in the camera's metric frame:
``(xn, yn) = (q_x, -q_y) / standoff``, radial distortion ``xd = xn (1 + k1 r^2 + k2 r^4)``,
``u = cx + fx xd``, ``v = cy + fy yd``.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_control.kinematics import wrap_angle

UNDISTORT_ITERATIONS = 8


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics [px]; ``distortion`` in ROS plumb_bob order (k1, k2, p1, p2, k3)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...]

    @property
    def k1(self) -> float:
        return self.distortion[0]

    @property
    def k2(self) -> float:
        return self.distortion[1]


def rotation(phi: float) -> np.ndarray:
    """2-D rotation matrix of angle ``phi`` [rad]."""
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s], [s, c]])


class CameraModel:
    """Intrinsics, standoff and mounting offset of the tip camera."""

    def __init__(self, intrinsics: Intrinsics, standoff: float,
                 offset: Sequence[float]) -> None:
        if standoff <= 0 or intrinsics.fx <= 0 or intrinsics.fy <= 0:
            raise ValueError('standoff, fx and fy must be positive')
        if intrinsics.width <= 0 or intrinsics.height <= 0:
            raise ValueError('image size must be positive')
        self.intrinsics = intrinsics
        self.standoff = float(standoff)
        self.offset = np.asarray(offset, dtype=float).reshape(2)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CameraModel:
        """From the ``camera.*`` tree of config/camera.yaml."""
        intrinsics = Intrinsics(
            width=int(d['width']), height=int(d['height']), fx=float(d['fx']),
            fy=float(d['fy']), cx=float(d['cx']), cy=float(d['cy']),
            distortion=(float(d.get('k1', 0.0)), float(d.get('k2', 0.0)), 0.0, 0.0, 0.0))
        return cls(intrinsics, float(d['standoff']), d['offset'])

    @property
    def scale(self) -> float:
        """Mean plate distance per pixel at the principal point [m/px]."""
        return self.standoff * 2.0 / (self.intrinsics.fx + self.intrinsics.fy)

    def optical_centre(self, pose: Sequence[float]) -> np.ndarray:
        """Plate point on the optical axis for tip pose (x, y, phi) [m]."""
        x, y, phi = pose
        return np.array([x, y]) + rotation(phi) @ self.offset

    def tip_from_camera(self, centre: np.ndarray, phi: float) -> np.ndarray:
        """Tip pose (x, y, phi) from the optical centre on the plate and the tool angle."""
        x, y = np.asarray(centre, dtype=float) - rotation(phi) @ self.offset
        return np.array([x, y, wrap_angle(phi)])

    def metric_to_pixels(self, q: np.ndarray) -> np.ndarray:
        """Camera metric points (N, 2) [m] -> pixels (N, 2), with distortion."""
        i = self.intrinsics
        xn = q[:, 0] / self.standoff
        yn = -q[:, 1] / self.standoff
        factor = self._radial(xn * xn + yn * yn)
        return np.column_stack([i.cx + i.fx * xn * factor, i.cy + i.fy * yn * factor])

    def pixels_to_metric(self, pixels: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) -> camera metric points (N, 2) [m], undistorted (fixed point)."""
        i = self.intrinsics
        xd = (pixels[:, 0] - i.cx) / i.fx
        yd = (pixels[:, 1] - i.cy) / i.fy
        xn, yn = xd, yd
        if i.k1 or i.k2:
            for _ in range(UNDISTORT_ITERATIONS):
                factor = self._radial(xn * xn + yn * yn)
                xn, yn = xd / factor, yd / factor
        return np.column_stack([xn * self.standoff, -yn * self.standoff])

    def magnification(self, metric: np.ndarray) -> np.ndarray:
        """Area-equivalent local lens magnification at camera metric points (N, 2) (1 = none)."""
        k1, k2 = self.intrinsics.k1, self.intrinsics.k2
        r2 = np.sum(metric * metric, axis=1) / self.standoff ** 2
        tangential = self._radial(r2)
        radial = tangential + 2.0 * r2 * (k1 + 2.0 * k2 * r2)
        return np.sqrt(tangential * radial)

    def _radial(self, r2: np.ndarray) -> np.ndarray:
        return 1.0 + self.intrinsics.k1 * r2 + self.intrinsics.k2 * r2 * r2
