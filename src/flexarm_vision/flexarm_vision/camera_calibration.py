"""The camera's own parameters, from images of the hole plate at several arm poses (pure).

The plate is a calibration target of known geometry, so the holes a set of images decodes
(:meth:`~flexarm_vision.pose_estimator.TipPoseEstimator.match`) calibrate the camera as any
target does: OpenCV's ``calibrateCamera`` over the views, each view's plate pose free. What a
plate seen square-on from a fixed stand-off can and cannot tell:

- **determined**: the radial distortion k1, k2 (the holes' pattern bends with the radius), and
  the focal length *relative to the stand-off* (the plate's scale in the image: the fit is run
  with the focal length held, and the plate's fitted distance against the configured stand-off
  gives the ratio);
- **not determined**: the focal length and the stand-off separately (a plate twice as far seen
  through twice the focal length looks the same), the principal point (a shift of it moves
  every view's plate position alike: a tool offset) and the camera's yaw on the tool (a tool
  angle). The tool calibration against a reference (``flexarm calibrate``) measures those two
  as the camera's error in the tool frame; tangential distortion and k3 are kept as the
  camera_info says (a fronto-parallel plate separates them poorly from the rest).

:class:`CameraCorrection` holds the result as a change of the camera's calibration (its
camera_info): a factor on fx and fy, and what k1 and k2 gain.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from flexarm_core.calibration_record import read_record, write_record
from flexarm_vision.camera_model import CameraModel, Intrinsics

MIN_VIEWS = 3             # views of the plate at distinct tool angles a calibration needs
MIN_ANGLE_SPAN = math.radians(20)   # their tool angles must spread over this much
FLAGS = (cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_FOCAL_LENGTH
         | cv2.CALIB_FIX_PRINCIPAL_POINT | cv2.CALIB_FIX_TANGENT_DIST | cv2.CALIB_FIX_K3)
CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
PASSES = 2                # a second fit at the corrected focal length: k1, k2 refer to it
DETERMINED = 'focal length / stand-off, k1, k2'
NOT_DETERMINED = ('focal length and stand-off apart (only their ratio shows), principal point '
                  "and camera yaw (they act as a tool offset and angle: the reference "
                  'calibration measures them), tangential distortion and k3 (kept)')


@dataclass(frozen=True)
class CameraCorrection:
    """A change of the camera's calibration: fx, fy times ``focal_scale``; k1, k2 plus
    ``k1``, ``k2``. The neutral correction changes nothing."""

    focal_scale: float = 1.0
    k1: float = 0.0
    k2: float = 0.0

    @classmethod
    def from_list(cls, values: Sequence[float]) -> CameraCorrection:
        """From ``[focal_scale, k1, k2]``; ValueError unless 3 finite values and a focal
        scale within 0.5..2."""
        values = [float(v) for v in values]
        if len(values) != 3 or not all(math.isfinite(v) for v in values):
            raise ValueError(f'a camera correction is 3 finite values [focal scale, k1, k2], '
                             f'got {values}')
        if not 0.5 <= values[0] <= 2.0:
            raise ValueError(f'a focal scale of {values[0]:g} is no correction of a '
                             'calibrated camera (0.5..2)')
        return cls(*values)

    def as_list(self) -> list[float]:
        return [self.focal_scale, self.k1, self.k2]

    def __add__(self, other: CameraCorrection) -> CameraCorrection:
        """``other``, measured through this one, on top of it (exact for the focal scale; for
        k1, k2 to first order in the focal scale's change, a few parts in a thousand)."""
        return CameraCorrection(self.focal_scale * other.focal_scale, self.k1 + other.k1,
                                self.k2 + other.k2)

    def apply(self, intrinsics: Intrinsics) -> Intrinsics:
        """``intrinsics`` (the camera_info's) corrected."""
        k1, k2, *rest = intrinsics.distortion
        return dataclasses.replace(
            intrinsics, fx=intrinsics.fx * self.focal_scale, fy=intrinsics.fy * self.focal_scale,
            distortion=(k1 + self.k1, k2 + self.k2, *rest))

    def describe(self) -> str:
        return (f'focal length / stand-off {(self.focal_scale - 1) * 100:+.3f} %, '
                f'k1 {self.k1:+.5f}, k2 {self.k2:+.5f}')


@dataclass(frozen=True)
class CameraCalibration:
    """What :func:`calibrate_camera` found."""

    correction: CameraCorrection
    views: int
    holes: int
    rms_before_px: float      # reprojection error of the holes with the camera_info as it is
    rms_after_px: float       # ... and corrected
    determined: str = DETERMINED
    not_determined: str = NOT_DETERMINED


def calibrate_camera(camera: CameraModel, views: Sequence[tuple[np.ndarray, np.ndarray]],
                     angles: Sequence[float]) -> CameraCalibration:
    """The correction of ``camera``'s calibration that the holes of ``views`` show.

    ``views``: per image, the decoded holes' centres (n, 2) [px] and their plate centres
    (n, 2) [m]; ``angles`` the tool angles [rad] the images were taken at. ValueError with the
    reason when the views cannot determine it (too few, or all at one tool angle: the radial
    pattern then repeats the same holes).
    """
    if len(views) < MIN_VIEWS:
        raise ValueError(f'only {len(views)} images of the plate decoded: {MIN_VIEWS} or more '
                         'at distinct tool angles are needed')
    span = float(np.ptp(np.unwrap(np.asarray(angles, dtype=float))))
    if span < MIN_ANGLE_SPAN:
        raise ValueError(f'the images span {math.degrees(span):.1f} deg of tool angle: '
                         f'{math.degrees(MIN_ANGLE_SPAN):.0f} deg or more are needed')
    objects = [np.column_stack([p - p.mean(axis=0), np.zeros(len(p))]).astype(np.float32)
               for _, p in views]
    images = [np.asarray(px, dtype=np.float32).reshape(-1, 1, 2) for px, _ in views]
    i = camera.intrinsics
    size = (i.width, i.height)
    correction = CameraCorrection()
    rms_before = _reprojection_rms(objects, images, i, size)
    for _ in range(PASSES):
        guess = correction.apply(i)
        _, _, distortion, _, translations = cv2.calibrateCamera(
            objects, images, size, _matrix(guess), np.array(guess.distortion), flags=FLAGS,
            criteria=CRITERIA)
        distance = float(np.median([t[2, 0] for t in translations]))
        k1, k2 = (float(v) for v in distortion.ravel()[:2])
        correction = CameraCorrection(correction.focal_scale * camera.standoff / distance,
                                      k1 - i.k1, k2 - i.distortion[1])
    return CameraCalibration(correction, len(views), sum(len(p) for p, _ in views),
                             rms_before, _reprojection_rms(objects, images,
                                                           correction.apply(i), size))


def _matrix(i: Intrinsics) -> np.ndarray:
    return np.array([[i.fx, 0.0, i.cx], [0.0, i.fy, i.cy], [0.0, 0.0, 1.0]])


def _reprojection_rms(objects: list[np.ndarray], images: list[np.ndarray], i: Intrinsics,
                      size: tuple[int, int]) -> float:
    """RMS reprojection error [px] of the views with every intrinsic held at ``i``."""
    fixed = FLAGS | cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2
    rms = cv2.calibrateCamera(objects, images, size, _matrix(i), np.array(i.distortion),
                              flags=fixed, criteria=CRITERIA)[0]
    return float(rms)


def read_camera_calibration(path: str | Path) -> dict[str, Any] | None:
    """The camera calibration record at ``path`` (:func:`write_camera_calibration`), None if
    there is none; ValueError naming the file if it is damaged."""
    return read_record(path, 'camera_correction', CameraCorrection.from_list,
                       'camera calibration', 'flexarm calibrate --camera')


def write_camera_calibration(path: str | Path, correction: CameraCorrection,
                             **details: Any) -> None:
    """Store ``correction`` with ``details`` (how it was found) at ``path``, atomically."""
    write_record(path, 'camera_correction', correction.as_list(), **details)
