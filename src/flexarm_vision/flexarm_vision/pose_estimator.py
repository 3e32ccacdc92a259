"""Absolute tip pose from one image of the coded plate (pure).

Pipeline: detect holes (sub-pixel centres, sizes) -> undistort to the camera's metric frame ->
classify each hole's code symbol by diameter -> find the grid (angle modulo 90 deg, integer
cell of every hole relative to a reference hole; off-grid blobs are dropped) -> decode: test
every plate position and quarter-turn of the observed cells against the plate code, demand an
exact and unambiguous match -> least-squares fit of the camera's metric points to the matched
plate holes: a rotation, and the scale and radial stretch the camera's calibration may have
wrong (:meth:`TipPoseEstimator._fit_pose`) -> tip pose through the camera-to-tip offset ->
residual check. Any failure gives ``valid=False`` with a reason, never an exception.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flexarm_vision.camera_model import CameraModel, rotation
from flexarm_vision.hole_detector import DetectorSettings, HoleDetector
from flexarm_vision.plate import PlateLayout

UNKNOWN = -1              # symbol of a hole whose size lies between two code diameters
OFF_PLATE = -2            # code value outside the plate: matches no observed hole
QUARTER_TURN = np.array([[0, 1], [-1, 0]])   # row vectors @ this = turned by +90 deg


@dataclass(frozen=True)
class Estimate:
    """Result of one image: tip pose (x, y, phi) [m, rad] only when ``valid``."""

    pose: np.ndarray | None
    valid: bool
    holes_used: int
    residual: float       # RMS distance of the matched holes from their fitted plate position [m]
    status: str           # reason when not valid, '' otherwise
    scale: float = 1.0    # plate seen this much larger than the camera's calibration says
    radial: float = 0.0   # radial stretch at the holes' RMS radius the calibration does not hold


@dataclass(frozen=True)
class FitSettings:
    min_holes: int                # fewer matched holes: invalid
    max_residual: float           # [m] RMS fit residual above which the pose is invalid
    max_hole_residual: float      # [m] largest single-hole residual allowed
    max_scale_error: float        # plate scale beyond 1 -/+ this: the camera model is wrong
    grid_tolerance: float         # fraction of the pitch a hole may lie off its grid cell
    min_grid_coherence: float     # agreement of neighbour directions (1 = perfect grid)
    size_tolerance: float         # [m] diameter deviation still assigned to a code symbol
    max_code_errors: int          # holes allowed to disagree with the decoded plate code
    code_margin: int              # extra disagreements the next best plate position must have

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> FitSettings:
        s = cls(min_holes=int(d['min_holes']), max_residual=float(d['max_residual']),
                max_hole_residual=float(d['max_hole_residual']),
                max_scale_error=float(d['max_scale_error']),
                grid_tolerance=float(d['grid_tolerance']),
                min_grid_coherence=float(d['min_grid_coherence']),
                size_tolerance=float(d['size_tolerance']),
                max_code_errors=int(d['max_code_errors']), code_margin=int(d['code_margin']))
        if (s.min_holes < 3 or min(s.max_residual, s.max_hole_residual, s.size_tolerance,
                                   s.max_scale_error) <= 0
                or not 0 < s.grid_tolerance < 0.5 or s.max_code_errors < 0
                or s.code_margin < 1):
            raise ValueError(f'invalid fit settings {s}')
        return s


class TipPoseEstimator:
    """Image -> absolute tip pose, for one plate and camera."""

    def __init__(self, plate: PlateLayout, camera: CameraModel, fit: FitSettings,
                 detector: DetectorSettings) -> None:
        self.plate = plate
        self.camera = camera
        self.fit = fit
        self.detector = HoleDetector(detector, min(plate.diameters) / camera.scale,
                                     max(plate.diameters) / camera.scale)
        i, j = plate.shape
        self._pad = int(math.ceil(math.hypot(camera.intrinsics.width, camera.intrinsics.height)
                                  * camera.scale / plate.pitch)) + 1
        self._code = np.full((i + 2 * self._pad, j + 2 * self._pad), OFF_PLATE, np.int8)
        self._code[self._pad:self._pad + i, self._pad:self._pad + j] = plate.symbols

    @classmethod
    def from_dict(cls, d: Mapping[str, Mapping[str, Any]]) -> TipPoseEstimator:
        """From the ``plate``, ``camera`` (camera.yaml) and ``vision`` (vision.yaml) trees."""
        return cls(PlateLayout.from_dict(d['plate']), CameraModel.from_dict(d['camera']),
                   FitSettings.from_dict(d['vision']), DetectorSettings.from_dict(d['vision']))

    def with_camera(self, camera: CameraModel) -> TipPoseEstimator:
        """The same plate and settings seen through another camera model."""
        return TipPoseEstimator(self.plate, camera, self.fit, self.detector.settings)

    def estimate(self, image: Any) -> Estimate:
        """Tip pose from a mono8 image of the configured size; invalid with a reason if not."""
        matched = self.match(image)
        if isinstance(matched, Estimate):
            return matched
        pixels, plate_points = matched
        return self._fit_pose(self.camera.pixels_to_metric(pixels), plate_points)

    def match(self, image: Any) -> tuple[np.ndarray, np.ndarray] | Estimate:
        """The decoded holes of an image: their centres (n, 2) [px] and the plate centres
        (n, 2) [m] they are; an invalid :class:`Estimate` with the reason if the image does
        not decode. What a camera calibration from the plate takes
        (:mod:`flexarm_vision.camera_calibration`)."""
        i = self.camera.intrinsics
        if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 2:
            kind = (f'{image.dtype} array of shape {image.shape}'
                    if isinstance(image, np.ndarray) else type(image).__name__)
            return _invalid(f'expected a 2-D uint8 image, got {kind}')
        if image.shape != (i.height, i.width):
            return _invalid(f'expected a {i.width}x{i.height} image, '
                            f'got {image.shape[1]}x{image.shape[0]}')
        detection = self.detector.detect(image)
        if detection.status:
            return _invalid(detection.status)
        pixels = detection.centres
        metric = self.camera.pixels_to_metric(pixels)
        diameters = (detection.diameters * self.camera.scale
                     / self.camera.magnification(metric))
        symbols = self._classify(diameters)
        kept = symbols != OFF_PLATE
        pixels, metric, symbols = pixels[kept], metric[kept], symbols[kept]
        if len(metric) < self.fit.min_holes:
            return _invalid(f'too few holes: {len(metric)} < {self.fit.min_holes}', len(metric))
        cells, reason = self._grid_cells(metric)
        if cells is None:
            return _invalid(reason, len(metric))
        inliers = cells[:, 0] != np.iinfo(np.int64).min
        pixels, metric, symbols, cells = (pixels[inliers], metric[inliers], symbols[inliers],
                                          cells[inliers])
        if len(metric) < self.fit.min_holes:
            return _invalid(f'too few holes on the grid: {len(metric)} < {self.fit.min_holes}',
                            len(metric))
        plate_points, reason = self._decode(cells, symbols)
        if plate_points is None:
            return _invalid(reason, len(metric))
        return np.asarray(pixels, dtype=float), plate_points

    def _classify(self, diameters: np.ndarray) -> np.ndarray:
        """Code symbol per hole; UNKNOWN between two diameters, OFF_PLATE if no hole size."""
        reference = np.array(self.plate.diameters)
        distance = np.abs(diameters[:, None] - reference[None, :])
        symbols = np.argmin(distance, axis=1).astype(np.int64)
        close = distance[np.arange(len(diameters)), symbols] <= self.fit.size_tolerance
        in_range = ((diameters >= reference[0] - self.fit.size_tolerance)
                    & (diameters <= reference[-1] + self.fit.size_tolerance))
        return np.where(close, symbols, np.where(in_range, UNKNOWN, OFF_PLATE))

    def _grid_cells(self, metric: np.ndarray) -> tuple[np.ndarray | None, str]:
        """Integer grid cell (a, b) of each hole relative to a reference hole, in grid axes.

        Rows of off-grid holes are set to int64 min. The grid axes are the camera's axes turned
        by the grid angle beta (modulo 90 deg): plate = R(k 90 deg) (cell) for some quarter-turn.
        """
        pitch = self.plate.pitch
        tol = self.fit.grid_tolerance
        delta = metric[None, :, :] - metric[:, None, :]
        length = np.hypot(delta[..., 0], delta[..., 1])
        neighbours = np.abs(length - pitch) < tol * pitch
        if not np.any(neighbours):
            return None, 'no hole grid: no two holes one pitch apart'
        theta = np.arctan2(delta[..., 1][neighbours], delta[..., 0][neighbours])
        mean = np.mean(np.exp(4j * theta))
        if abs(mean) < self.fit.min_grid_coherence:
            return None, f'no consistent hole grid (direction coherence {abs(mean):.2f})'
        beta = np.angle(mean) / 4
        grid = metric @ rotation(beta) / pitch          # rows: R(-beta) q / pitch
        offsets = grid[None, :, :] - grid[:, None, :]   # [reference, hole]
        cells = np.rint(offsets)
        on_grid = np.all(np.abs(offsets - cells) < tol, axis=2)
        reference = int(np.argmax(on_grid.sum(axis=1)))
        result = cells[reference].astype(np.int64)
        result[~on_grid[reference]] = np.iinfo(np.int64).min
        kept = result[on_grid[reference]]
        if len(np.unique(kept, axis=0)) != len(kept):
            return None, 'two holes on one grid cell'
        return result, ''

    def _decode(self, cells: np.ndarray,
                symbols: np.ndarray) -> tuple[np.ndarray | None, str]:
        """Plate centres of the holes, from the unique plate position matching their code.

        Candidates are (quarter-turn k, plate index of the reference hole); hole after hole,
        candidates with more disagreements than a valid answer or its closest rival may have
        are dropped, so the survivors decide both the match and its margin.
        """
        ni, nj = self.plate.shape
        if np.any(np.abs(cells) >= self._pad):
            return None, 'holes spread wider than the field of view'
        turned = np.stack([cells @ np.linalg.matrix_power(QUARTER_TURN, k) for k in range(4)])
        k, i0, j0 = (a.ravel() for a in np.meshgrid(np.arange(4), np.arange(ni), np.arange(nj),
                                                       indexing='ij'))
        errors = np.zeros(len(k), np.int64)
        limit = self.fit.max_code_errors + self.fit.code_margin - 1
        for n, symbol in enumerate(symbols):
            code = self._code[self._pad + i0 + turned[k, n, 0], self._pad + j0 + turned[k, n, 1]]
            errors += (code != symbol) if symbol >= 0 else (code == OFF_PLATE)
            keep = errors <= limit
            k, i0, j0, errors = k[keep], i0[keep], j0[keep], errors[keep]
        order = np.argsort(errors)
        if len(order) == 0 or errors[order[0]] > self.fit.max_code_errors:
            return None, 'plate code not found (no place of the plate matches the holes)'
        if len(order) > 1 and errors[order[1]] - errors[order[0]] < self.fit.code_margin:
            return None, (f'ambiguous plate code ({errors[order[0]]} and {errors[order[1]]} '
                          f'disagreeing holes, {int(np.sum(symbols >= 0))} of known code)')
        best = order[0]
        index = turned[k[best]] + np.array([i0[best], j0[best]])
        return self.plate.centre(index[:, 0], index[:, 1]), ''

    def _fit_pose(self, metric: np.ndarray, plate_points: np.ndarray) -> Estimate:
        """Fit plate = c + a (m + k m |m|^2 / r^2) (complex numbers: a turns and scales, k
        bends radially, r the holes' RMS radius), so a camera whose focal length, stand-off or
        radial distortion is a little off its calibration still measures; tip pose from c (the
        optical centre, m = 0) and arg a; residual checks on what that leaves. The radial term
        is fitted only with more holes than the least that decode, and as a pure radial
        stretch: a free complex term would trade with the angle (2.5 times its noise)."""
        m = metric[:, 0] + 1j * metric[:, 1]
        p = plate_points[:, 0] + 1j * plate_points[:, 1]
        similar = np.column_stack([np.ones_like(m), m])
        c, a = np.linalg.lstsq(similar, p, rcond=None)[0]
        if len(m) > self.fit.min_holes:
            bend = a * m * np.abs(m) ** 2 / max(float(np.mean(np.abs(m) ** 2)), 1e-12)
            design = np.vstack([
                np.column_stack([np.ones(len(m)), np.zeros(len(m)), m.real, -m.imag, bend.real]),
                np.column_stack([np.zeros(len(m)), np.ones(len(m)), m.imag, m.real, bend.imag])])
            x = np.linalg.lstsq(design, np.concatenate([p.real, p.imag]), rcond=None)[0]
            c, a, radial = complex(x[0], x[1]), complex(x[2], x[3]), float(x[4])
            fitted = c + a * m + radial * bend
        else:
            radial, fitted = 0.0, c + a * m
        n, scale = len(metric), 1.0 / max(abs(a), 1e-12)     # metric points too large: a < 1
        if abs(scale - 1.0) > self.fit.max_scale_error:
            return _invalid(f'plate seen {(scale - 1.0) * 100:+.1f} % off the scale of the '
                            "camera's calibration (its focal length or stand-off is not what "
                            'camera_info says)', n)
        phi = float(np.angle(a))
        centre = np.array([c.real, c.imag])
        errors = np.abs(p - fitted)
        rms = float(np.sqrt(np.mean(errors ** 2)))
        if rms > self.fit.max_residual:
            return _invalid(f'fit residual {rms * 1e3:.3f} mm RMS too large', n, rms)
        if errors.max() > self.fit.max_hole_residual:
            return _invalid(f'hole off its fitted position by {errors.max() * 1e3:.3f} mm',
                            n, rms)
        return Estimate(self.camera.tip_from_camera(centre, phi), True, n, rms, '',
                        scale, radial)


def _invalid(status: str, holes: int = 0, residual: float = 0.0) -> Estimate:
    return Estimate(None, False, holes, residual, status)
