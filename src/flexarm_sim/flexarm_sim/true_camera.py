"""The true tip camera, as it differs from its calibration (config/sim.yaml
``error_sources.camera``).

The renderer draws what the real camera sees: its own focal length, principal point and radial
distortion (k1, k2), its own mounting on the tip (offset, and a yaw about its optical axis) and
the plate as manufactured, every hole a fixed random error off its nominal centre. The vision
node and the simulator's camera_info keep the calibration of config/camera.yaml. Every error is
true minus believed. A constant error of the camera in the tool frame is a floor for every mode:
the learner learns the camera's pose, not the tool's.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_sim.camera import CameraRenderer, RenderSettings
from flexarm_sim.errors import active, seeded
from flexarm_vision.camera_model import CameraModel
from flexarm_vision.plate import PlateLayout

HOLE_STREAM = 1           # generator of the hole errors among the error_sources streams


@dataclass(frozen=True)
class CameraErrors:
    focal_length: float                   # relative error of fx and fy
    principal_point: tuple[float, float]  # [px] of cx, cy
    k1: float                             # of the radial distortion's r^2 term
    k2: float                             # ... and its r^4 term
    mount_yaw: float                      # [rad] about the optical axis
    mount_offset: tuple[float, float]     # [m] of the offset, tip frame
    hole_sigma: float                     # [m] per hole and axis

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CameraErrors | None:
        """From config/sim.yaml ``error_sources.*``; None while the source is off."""
        if not active(d, 'camera'):
            return None
        c = d['camera']
        errors = cls(float(c['focal_length']), _pair(c['principal_point']), float(c['k1']),
                     float(c['k2']), float(c['mount_yaw']), _pair(c['mount_offset']),
                     float(c['hole_sigma']))
        if errors.focal_length <= -1 or errors.hole_sigma < 0:
            raise ValueError('error_sources.camera: focal_length > -1 and hole_sigma >= 0')
        return errors


class ManufacturedPlate(PlateLayout):
    """A plate whose hole (i, j) sits ``errors[i, j]`` [m] off its nominal centre."""

    def __init__(self, plate: PlateLayout, errors: np.ndarray) -> None:
        super().__init__(plate.pitch, plate.origin, plate.diameters, plate.symbols)
        if errors.shape != (*plate.shape, 2):
            raise ValueError(f'hole errors must have shape {(*plate.shape, 2)}')
        self.errors = errors

    def centre(self, i: int | np.ndarray, j: int | np.ndarray) -> np.ndarray:
        return super().centre(i, j) + self.errors[i, j]


def true_renderer(camera_config: Mapping[str, Mapping[str, Any]],
                  error_sources: Mapping[str, Any]) -> CameraRenderer:
    """The renderer of the real camera: config/camera.yaml's ``plate``, ``camera`` and
    ``camera_render`` trees, with config/sim.yaml's ``error_sources`` camera errors if on."""
    errors = CameraErrors.from_dict(error_sources)
    if errors is None:
        return CameraRenderer.from_dict(camera_config)
    plate = PlateLayout.from_dict(camera_config['plate'])
    believed = CameraModel.from_dict(camera_config['camera'])
    i = believed.intrinsics
    scale = 1.0 + errors.focal_length
    (dcx, dcy), (k1, k2, *rest) = errors.principal_point, i.distortion
    intrinsics = dataclasses.replace(i, fx=i.fx * scale, fy=i.fy * scale, cx=i.cx + dcx,
                                     cy=i.cy + dcy,
                                     distortion=(k1 + errors.k1, k2 + errors.k2, *rest))
    camera = CameraModel(intrinsics, believed.standoff, believed.offset + errors.mount_offset)
    holes = seeded(error_sources, HOLE_STREAM).normal(0.0, errors.hole_sigma, (*plate.shape, 2))
    return CameraRenderer(ManufacturedPlate(plate, holes), camera,
                          RenderSettings.from_dict(camera_config['camera_render']),
                          errors.mount_yaw)


def _pair(values: Any) -> tuple[float, float]:
    first, second = (float(v) for v in values)
    return first, second
