"""Dark round holes in a mono8 image of the plate: sub-pixel centres and sizes (pure, OpenCV).

1. The plate level is the image median (holes cover a few percent of the view); a dark or
   saturated image is refused.
2. Pixels darker than ``threshold`` x plate level are segmented into connected components;
   components of the wrong size or shape (not a disc), or whose measuring window would leave
   the image (holes cut by the border), are rejected.
3. In a window around each component: local background = mean of the window's rim, depth =
   background - (nearly) darkest pixel; darkness = background - pixel. The centre is the
   darkness-weighted centroid above a floor of ``weight_floor`` x depth (removes noise and
   background offsets; the weights stay symmetric about the true centre); the size is the
   area-equivalent diameter of the coverage sum(darkness / depth), which blur does not change.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

DARKEST_RANK = 3          # depth from the 4th darkest pixel: robust to single noisy pixels


@dataclass(frozen=True)
class DetectorSettings:
    threshold: float               # segmentation level, fraction of the plate level
    min_plate_level: float         # [DN] darker plate: image refused
    max_saturated_fraction: float  # fraction of 255-pixels above which the image is refused
    max_aspect: float              # bounding box long / short side of a hole
    min_fill: float                # component area / bounding box area (disc: pi/4)
    max_fill: float
    roi_margin: int                # [px] measuring window beyond the component
    weight_floor: float            # fraction of the hole depth ignored by the centroid
    size_slack: float              # accepted relative deviation from the hole diameter range

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> DetectorSettings:
        s = cls(threshold=float(d['threshold']), min_plate_level=float(d['min_plate_level']),
                max_saturated_fraction=float(d['max_saturated_fraction']),
                max_aspect=float(d['max_aspect']), min_fill=float(d['min_fill']),
                max_fill=float(d['max_fill']), roi_margin=int(d['roi_margin']),
                weight_floor=float(d['weight_floor']), size_slack=float(d['size_slack']))
        if not (0 < s.threshold < 1 and 0 <= s.weight_floor < 1 and s.max_aspect >= 1
                and 0 < s.min_fill < s.max_fill <= 1 and s.roi_margin >= 1
                and 0 <= s.size_slack < 1):
            raise ValueError(f'invalid detector settings {s}')
        return s


@dataclass(frozen=True)
class HoleDetection:
    """Detected holes: centres (N, 2) [px, (u, v)], diameters (N,) [px]; status if refused."""

    centres: np.ndarray
    diameters: np.ndarray
    rejected: int = 0
    status: str = ''


class HoleDetector:
    """Finds holes of ``min_diameter``..``max_diameter`` pixels in a mono8 image."""

    def __init__(self, settings: DetectorSettings, min_diameter: float,
                 max_diameter: float) -> None:
        if not 0 < min_diameter <= max_diameter:
            raise ValueError('hole diameter range must be positive and ordered')
        self.settings = settings
        self.min_diameter = min_diameter
        self.max_diameter = max_diameter

    def detect(self, image: np.ndarray) -> HoleDetection:
        """Holes of ``image`` (uint8, 2-D; the caller checks type and size)."""
        s = self.settings
        hist = cv2.calcHist([image], [0], None, [256], [0, 256]).ravel()
        plate_level = float(np.searchsorted(np.cumsum(hist), image.size / 2))
        if plate_level < s.min_plate_level:
            return _refused(f'image too dark (plate level {plate_level:.0f} DN)')
        if hist[255] > s.max_saturated_fraction * image.size:
            return _refused(f'image saturated ({hist[255] / image.size:.0%} at 255)')
        _, mask = cv2.threshold(image, s.threshold * plate_level, 1, cv2.THRESH_BINARY_INV)
        _, _, stats, _ = cv2.connectedComponentsWithStatsWithAlgorithm(
            mask, 8, cv2.CV_32S, cv2.CCL_BBDT)
        stats = stats[1:]
        candidates = stats[self._plausible(stats, image.shape)]
        centres, diameters = [], []
        for left, top, w, h, _ in candidates:
            measured = self._measure(image, left, top, w, h)
            if measured is not None:
                centres.append(measured[0])
                diameters.append(measured[1])
        return HoleDetection(np.array(centres, dtype=float).reshape(-1, 2),
                             np.array(diameters, dtype=float), rejected=len(stats) - len(centres))

    def _plausible(self, stats: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
        """Components that may be whole holes: size, shape, measuring window inside image."""
        s = self.settings
        left, top, w, h, area = stats.T
        margin = s.roi_margin
        long_side, short_side = np.maximum(w, h), np.maximum(np.minimum(w, h), 1)
        fill = area / (w * h)
        low, high = self._size_range()
        return ((long_side >= low) & (long_side <= high)
                & (long_side <= s.max_aspect * short_side)
                & (fill >= s.min_fill) & (fill <= s.max_fill)
                & (left >= margin) & (top >= margin)
                & (left + w + margin <= shape[1]) & (top + h + margin <= shape[0]))

    def _measure(self, image: np.ndarray, left: int, top: int, w: int,
                 h: int) -> tuple[np.ndarray, float] | None:
        """(centre [px], area-equivalent diameter [px]) of the hole in a component's window."""
        m = self.settings.roi_margin
        u0, v0 = left - m, top - m
        roi = image[v0:top + h + m, u0:left + w + m].astype(np.float32)
        rim = np.concatenate([roi[0], roi[-1], roi[1:-1, 0], roi[1:-1, -1]])
        background = float(rim.mean())
        darkest = float(np.partition(roi.ravel(), DARKEST_RANK)[DARKEST_RANK])
        depth = background - darkest
        if depth <= 0:
            return None
        darkness = background - roi
        weights = np.maximum(darkness - self.settings.weight_floor * depth, 0.0)
        total = float(weights.sum())
        if total <= 0:
            return None
        rows, cols = roi.shape
        u = float(weights.sum(axis=0) @ np.arange(cols)) / total + u0
        v = float(weights.sum(axis=1) @ np.arange(rows)) / total + v0
        area = float(np.clip(darkness / depth, 0.0, 1.0).sum())
        diameter = 2.0 * math.sqrt(area / math.pi)
        low, high = self._size_range()
        if not low <= diameter <= high:
            return None
        return np.array([u, v]), diameter

    def _size_range(self) -> tuple[float, float]:
        slack = self.settings.size_slack
        return self.min_diameter * (1 - slack), self.max_diameter * (1 + slack)


def _refused(status: str) -> HoleDetection:
    return HoleDetection(np.zeros((0, 2)), np.zeros(0), status=status)
