"""Tip camera geometry: plate coordinates <-> pixels for a tip pose (pure, shared by the
simulated camera and the pose estimator).

The camera looks perpendicularly at the plate (the base x-y plane) from the arm's side, from a
fixed standoff. Its optical axis meets the plate at ``c = t + R(phi) offset``, where ``t`` is
the tip position, ``phi`` the tool angle and ``offset`` the camera-to-tip offset in the tip
frame. The image u axis is the tool axis (tip-frame x), the image v axis points along the
tip-frame -y (image rows grow downwards, plate y grows upwards), so the view is not mirrored.
Pixel centres are at integer coordinates; (cx, cy) is the principal point.

Per-point mapping, with ``q = R(phi)^T (p - c)`` the plate point in the camera's metric frame:
``(xn, yn) = (q_x, -q_y) / standoff``, then the ROS/OpenCV plumb_bob distortion (radial k1, k2,
k3 and tangential p1, p2): ``xd = xn R + 2 p1 xn yn + p2 (r^2 + 2 xn^2)``,
``yd = yn R + p1 (r^2 + 2 yn^2) + 2 p2 xn yn`` with ``R = 1 + k1 r^2 + k2 r^4 + k3 r^6``, and
``u = cx + fx xd``, ``v = cy + fy yd``.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from flexarm_core.kinematics import wrap_angle

# cv2.undistortPoints: fixed-point iterations until converged far below a pixel's 1e-6.
UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-12)


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

    @classmethod
    def from_k_d(cls, width: int, height: int, k: Sequence[float],
                 d: Sequence[float]) -> Intrinsics:
        """From a CameraInfo's 3x3 ``K`` (row-major) and plumb_bob ``D`` (up to 5 values)."""
        if len(k) != 9 or len(d) > 5:
            raise ValueError(f'expected a 3x3 K and at most 5 plumb_bob D values, got '
                             f'{len(k)} and {len(d)}')
        if k[1] != 0.0:
            raise ValueError(f'a skewed camera (K[0][1] = {k[1]:g}) is not supported')
        distortion = tuple(float(v) for v in d) + (0.0,) * (5 - len(d))
        return cls(int(width), int(height), float(k[0]), float(k[4]), float(k[2]),
                   float(k[5]), distortion)

    @property
    def k1(self) -> float:
        return self.distortion[0]

    @property
    def k2(self) -> float:
        return self.distortion[1]

    @property
    def k3(self) -> float:
        return self.distortion[4]

    @property
    def tangential(self) -> tuple[float, float]:
        """(p1, p2)."""
        return self.distortion[2], self.distortion[3]


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
            distortion=tuple(float(d.get(name, 0.0)) for name in ('k1', 'k2', 'p1', 'p2', 'k3')))
        return cls(intrinsics, float(d['standoff']), d['offset'])

    def with_intrinsics(self, intrinsics: Intrinsics) -> CameraModel:
        """The same mounting with other intrinsics (e.g. from the camera's CameraInfo)."""
        return CameraModel(intrinsics, self.standoff, self.offset)

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
        shift_x, shift_y = self._tangential(xn, yn)
        factor = self._radial(xn * xn + yn * yn)
        return np.column_stack([i.cx + i.fx * (xn * factor + shift_x),
                                i.cy + i.fy * (yn * factor + shift_y)])

    def pixels_to_metric(self, pixels: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) -> camera metric points (N, 2) [m], undistorted by OpenCV."""
        i = self.intrinsics
        pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 1, 2)
        if not len(pixels):
            return np.zeros((0, 2))
        k = np.array([[i.fx, 0.0, i.cx], [0.0, i.fy, i.cy], [0.0, 0.0, 1.0]])
        normalised = cv2.undistortPoints(pixels, k, np.asarray(i.distortion),
                                         criteria=UNDISTORT_CRITERIA).reshape(-1, 2)
        return np.column_stack([normalised[:, 0] * self.standoff,
                                -normalised[:, 1] * self.standoff])

    def magnification(self, metric: np.ndarray) -> np.ndarray:
        """Area-equivalent local lens magnification at camera metric points (N, 2) (1 = none):
        the square root of the distortion's Jacobian determinant."""
        i = self.intrinsics
        p1, p2 = i.tangential
        x, y = metric[:, 0] / self.standoff, -metric[:, 1] / self.standoff
        r2 = x * x + y * y
        radial = self._radial(r2)
        slope = i.k1 + 2.0 * i.k2 * r2 + 3.0 * i.k3 * r2 * r2      # d radial / d r^2
        cross = 2.0 * x * y * slope + 2.0 * p1 * x + 2.0 * p2 * y
        dxx = radial + 2.0 * x * x * slope + 2.0 * p1 * y + 6.0 * p2 * x
        dyy = radial + 2.0 * y * y * slope + 6.0 * p1 * y + 2.0 * p2 * x
        return np.sqrt(dxx * dyy - cross * cross)

    def _radial(self, r2: np.ndarray) -> np.ndarray:
        i = self.intrinsics
        return 1.0 + r2 * (i.k1 + r2 * (i.k2 + r2 * i.k3))

    def _tangential(self, xn: np.ndarray, yn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p1, p2 = self.intrinsics.tangential
        r2 = xn * xn + yn * yn
        return (2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn),
                p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn)
