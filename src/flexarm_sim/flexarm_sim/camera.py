"""Synthetic tip camera: mono images of the coded hole plate at a tip pose (pure).

Geometry is exact to sub-pixel level: each hole is drawn as its area coverage of every pixel,
computed from the signed distance of ``supersampling``^2 sub-samples per pixel to the hole edge
(a linear ramp one sub-sample wide), through the same :class:`CameraModel` (incl. distortion)
that the estimator inverts. On top: Gaussian defocus blur, a linear illumination gradient,
motion blur (the mean of sub-exposures along the tip velocity during the shutter time) and
Gaussian sensor noise, then 8-bit quantisation with saturation. ``mount_yaw`` turns the camera
about its optical axis on the tip (:mod:`flexarm_sim.true_camera`; the model has none).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from flexarm_vision.camera_model import CameraModel, Intrinsics, rotation
from flexarm_vision.plate import PlateLayout

PATCH_MARGIN = 2          # [px] beyond the largest hole radius in a hole's drawing patch


@dataclass(frozen=True)
class RenderSettings:
    plate_level: float            # [DN]
    hole_level: float             # [DN]
    illumination_gradient: float  # relative change across the image width
    illumination_direction: float  # [rad] in the image
    noise_sigma: float            # [DN]
    defocus_sigma: float          # [px]
    motion_blur: bool
    exposure: float               # [s]
    max_motion_samples: int
    supersampling: int

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> RenderSettings:
        s = cls(plate_level=float(d['plate_level']), hole_level=float(d['hole_level']),
                illumination_gradient=float(d['illumination_gradient']),
                illumination_direction=float(d['illumination_direction']),
                noise_sigma=float(d['noise_sigma']), defocus_sigma=float(d['defocus_sigma']),
                motion_blur=bool(d['motion_blur']), exposure=float(d['exposure']),
                max_motion_samples=int(d['max_motion_samples']),
                supersampling=int(d['supersampling']))
        if (min(s.noise_sigma, s.defocus_sigma, s.exposure) < 0 or s.supersampling < 1
                or s.max_motion_samples < 1 or not 0 <= s.hole_level < s.plate_level <= 255):
            raise ValueError(f'invalid camera_render settings {s}')
        return s


class CameraRenderer:
    """Renders what the tip camera sees of the plate."""

    def __init__(self, plate: PlateLayout, camera: CameraModel, settings: RenderSettings,
                 mount_yaw: float = 0.0) -> None:
        self.plate = plate
        self.camera = camera
        self.settings = settings
        self.mount_yaw = float(mount_yaw)     # [rad]
        i = camera.intrinsics
        radius_px = max(plate.diameters) / 2 / camera.scale
        self._patch = 2 * math.ceil(radius_px * self._max_stretch() + PATCH_MARGIN) + 1
        ss = settings.supersampling
        sub = (np.arange(self._patch * ss, dtype=np.float32) - (ss - 1) / 2) / ss   # [px]
        self._sub_u, self._sub_v = np.meshgrid(sub, sub)
        self._view_radius = (math.hypot(i.width, i.height) / 2 * self._max_stretch()
                             + self._patch) * camera.scale
        u, v = np.meshgrid(np.arange(i.width, dtype=np.float32),
                           np.arange(i.height, dtype=np.float32))
        direction = settings.illumination_direction
        ramp = ((u - i.cx) * math.cos(direction) + (v - i.cy) * math.sin(direction)) / i.width
        illumination = 1.0 + settings.illumination_gradient * ramp
        self._lit_plate = (illumination * settings.plate_level).astype(np.float32)
        self._hole_contrast = (illumination * (settings.plate_level - settings.hole_level)
                               ).astype(np.float32)

    @classmethod
    def from_dict(cls, d: Mapping[str, Mapping[str, Any]]) -> CameraRenderer:
        """From the ``plate``, ``camera`` and ``camera_render`` trees of config/camera.yaml."""
        return cls(PlateLayout.from_dict(d['plate']), CameraModel.from_dict(d['camera']),
                   RenderSettings.from_dict(d['camera_render']))

    @property
    def intrinsics(self) -> Intrinsics:
        return self.camera.intrinsics

    def render(self, pose: Sequence[float], tip_velocity: Sequence[float] = (0.0, 0.0, 0.0),
               rng: np.random.Generator | None = None) -> np.ndarray:
        """Mono8 image (height, width) at tip pose (x, y, phi) [m, rad].

        ``tip_velocity`` (vx, vy, omega) [m/s, rad/s] blurs the image over the exposure when
        motion blur is on; ``rng`` draws the sensor noise (None: noise-free).
        """
        pose = np.asarray(pose, dtype=float)
        velocity = np.asarray(tip_velocity, dtype=float)
        if pose.shape != (3,) or velocity.shape != (3,) or not (
                np.all(np.isfinite(pose)) and np.all(np.isfinite(velocity))):
            raise ValueError(f'pose and tip_velocity must be 3 finite values: {pose}, {velocity}')
        s = self.settings
        samples = self._motion_samples(velocity) if s.motion_blur else 1
        coverage = np.zeros((self.intrinsics.height, self.intrinsics.width), np.float32)
        for tau in np.linspace(-s.exposure / 2, s.exposure / 2, samples) if samples > 1 else [0]:
            self._draw_holes(coverage, pose + velocity * tau, 1.0 / samples)
        if s.defocus_sigma > 0:
            coverage = cv2.GaussianBlur(coverage, (0, 0), s.defocus_sigma)
        image = cv2.subtract(self._lit_plate, cv2.multiply(self._hole_contrast, coverage))
        noise = np.zeros_like(image)
        if rng is not None and s.noise_sigma > 0:
            cv2.setRNGSeed(int(rng.integers(2**31 - 1)))
            cv2.randn(noise, 0.0, s.noise_sigma)
        return cv2.add(image, noise, dtype=cv2.CV_8U)     # rounds and saturates

    def _motion_samples(self, velocity: np.ndarray) -> int:
        """Sub-exposures: about one per pixel of image motion during the exposure."""
        i = self.intrinsics
        scale = self.camera.scale
        reach = math.hypot(i.width, i.height) / 2 + math.hypot(*self.camera.offset) / scale
        blur_px = self.settings.exposure * (math.hypot(velocity[0], velocity[1]) / scale
                                            + abs(velocity[2]) * reach)
        return int(min(self.settings.max_motion_samples, math.ceil(blur_px) + 1))

    def _draw_holes(self, coverage: np.ndarray, pose: np.ndarray, weight: float) -> None:
        """Add ``weight`` x the hole coverage at ``pose`` into ``coverage`` (in place).

        Around each hole centre the lens mapping is linearised (its Jacobian), which is exact
        without distortion and leaves errors of order k1 (hole radius / f)^2 with it.
        """
        centre = self.camera.optical_centre(pose)
        index, centres = self.plate.holes_near(centre, self._view_radius)
        height, width = coverage.shape
        metric = (centres - centre) @ rotation(pose[2] + self.mount_yaw)
        pixels = self.camera.metric_to_pixels(metric)
        corner = np.rint(pixels).astype(int) - self._patch // 2
        inside = ((corner[:, 0] + self._patch > 0) & (corner[:, 0] < width)
                  & (corner[:, 1] + self._patch > 0) & (corner[:, 1] < height))
        if not np.any(inside):
            return
        index, metric = index[inside], metric[inside]
        pixels, corner = pixels[inside], corner[inside]
        radius = np.array(self.plate.diameters)[self.plate.symbols[index[:, 0], index[:, 1]]] / 2
        to_metric = np.linalg.inv(self._jacobians(metric)).astype(np.float32)   # (n, 2, 2)
        offset = (corner - pixels).astype(np.float32)
        du = offset[:, 0, None, None] + self._sub_u        # (n, P ss, P ss) [px]
        dv = offset[:, 1, None, None] + self._sub_v
        dx = to_metric[:, 0, 0, None, None] * du + to_metric[:, 0, 1, None, None] * dv
        dy = to_metric[:, 1, 0, None, None] * du + to_metric[:, 1, 1, None, None] * dv
        ss = self.settings.supersampling
        # Signed distance to the edge in sub-samples -> coverage (ramp one sub-sample wide)
        edge = (radius[:, None, None].astype(np.float32) - np.hypot(dx, dy)) * np.float32(
            ss / self.camera.scale) + np.float32(0.5)
        cover = np.clip(edge, 0.0, 1.0)
        if ss > 1:      # the mean of each pixel's ss x ss sub-samples, summed slice by slice
            blocks = cover.reshape(len(index), self._patch, ss, self._patch, ss)
            cover = sum(blocks[:, :, i, :, j] for i in range(ss) for j in range(ss)
                        ) * np.float32(1.0 / (ss * ss))
        for (u0, v0), patch in zip(corner, cover):
            u1, v1 = max(u0, 0), max(v0, 0)
            u2, v2 = min(u0 + self._patch, width), min(v0 + self._patch, height)
            coverage[v1:v2, u1:u2] += weight * patch[v1 - v0:v2 - v0, u1 - u0:u2 - u0]

    def _jacobians(self, metric: np.ndarray) -> np.ndarray:
        """d(pixel)/d(metric) at camera metric points (N, 2) -> (N, 2, 2), central differences."""
        step = 1e-4 * self.camera.standoff
        columns = []
        for axis in range(2):
            delta = np.zeros(2)
            delta[axis] = step
            columns.append((self.camera.metric_to_pixels(metric + delta)
                            - self.camera.metric_to_pixels(metric - delta)) / (2 * step))
        return np.stack(columns, axis=-1)

    def _max_stretch(self) -> float:
        """Largest radial magnification of the lens distortion inside the image (>= 1)."""
        i = self.intrinsics
        r2 = ((i.width / 2 / i.fx) ** 2 + (i.height / 2 / i.fy) ** 2)
        return max(1.0, 1.0 + abs(i.k1) * r2 + abs(i.k2) * r2 * r2) * 1.1
