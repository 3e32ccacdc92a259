"""The camera's error in the tool frame and the site file that keeps it (pure): the vision node
reports every pose through it, ``flexarm calibrate`` measures it against a reference
(:mod:`flexarm_control.execution.tool_calibration`) and writes the file atomically."""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from flexarm_core.calibration_record import read_record, write_record
from flexarm_core.kinematics import wrap_angle
from flexarm_core.measurement import Measurement


@dataclass(frozen=True)
class ToolCorrection:
    """The measured tool pose's error in the tool frame: measured minus true."""

    axial: float = 0.0      # [m] along the tool axis
    lateral: float = 0.0    # [m] across it (+: to the tool's left, the +phi side)
    angle: float = 0.0      # [rad]

    @classmethod
    def from_list(cls, values: Sequence[float]) -> ToolCorrection:
        """From ``[axial, lateral, angle]``; ValueError unless 3 finite values."""
        values = [float(v) for v in values]
        if len(values) != 3 or not all(math.isfinite(v) for v in values):
            raise ValueError(f'a tool correction is 3 finite values [m, m, rad], got {values}')
        return cls(*values)

    def as_list(self) -> list[float]:
        return [self.axial, self.lateral, self.angle]

    def __add__(self, other: ToolCorrection) -> ToolCorrection:
        """Both corrections (exact to first order: they are micrometres and millidegrees)."""
        return ToolCorrection(self.axial + other.axial, self.lateral + other.lateral,
                              self.angle + other.angle)

    def pose(self, measured: np.ndarray) -> np.ndarray:
        """The tool pose (3,) [m, m, rad] behind a measured one."""
        x, y, phi = (float(v) for v in measured)
        phi = wrap_angle(phi - self.angle)
        c, s = math.cos(phi), math.sin(phi)
        return np.array([x - c * self.axial + s * self.lateral,
                         y - s * self.axial - c * self.lateral, phi])

    def camera_mount(self, offset: Sequence[float]) -> np.ndarray:
        """Where the camera is in the tool frame, planar (along, across the tool axis, angle)
        [m, m, rad]: its nominal mount ``offset`` (config/camera.yaml, the URDF's tip ->
        camera) moved by this error. The vision node takes the tool from the camera through
        the nominal mount, so a camera there reports the tool's pose moved by this error,
        which :meth:`pose` removes."""
        c, s = math.cos(self.angle), math.sin(self.angle)
        along, across = (float(v) for v in offset)
        return np.array([self.axial + c * along - s * across,
                         self.lateral + s * along + c * across, self.angle])

    def apply(self, measurement: Measurement) -> Measurement:
        """The measurement with the correction applied to its pose."""
        return dataclasses.replace(measurement, pose=self.pose(measurement.pose))


def read_calibration(path: str | Path) -> dict[str, Any] | None:
    """The calibration record at ``path`` (:func:`write_calibration`), None if there is none;
    ValueError naming the file if it is damaged."""
    return read_record(path, 'tool_correction', ToolCorrection.from_list,
                       'tool calibration', 'flexarm calibrate')


def write_calibration(path: str | Path, correction: ToolCorrection, **details: Any) -> None:
    """Store ``correction`` with ``details`` (how it was found) at ``path``, atomically."""
    write_record(path, 'tool_correction', correction.as_list(), **details)
