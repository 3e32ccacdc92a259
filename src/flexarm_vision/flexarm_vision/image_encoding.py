"""Camera images in the common ROS encodings -> the 8-bit grey image the hole detector reads
(pure numpy/OpenCV).

Colour is reduced to luminance (cv2.cvtColor); Bayer mosaics are demosaiced to grey, with
cv_bridge's mapping of ROS pattern names to OpenCV codes; mono16 is taken at its 16-bit full
scale (value / 257), so a sensor's saturation stays 255.
"""
from __future__ import annotations

from typing import Any

import cv2
import numpy as np

# encoding -> (channels, bytes per channel)
LAYOUTS: dict[str, tuple[int, int]] = {
    'mono8': (1, 1), 'mono16': (1, 2), 'rgb8': (3, 1), 'bgr8': (3, 1), 'rgba8': (4, 1),
    'bgra8': (4, 1), 'bayer_rggb8': (1, 1), 'bayer_bggr8': (1, 1), 'bayer_gbrg8': (1, 1),
    'bayer_grbg8': (1, 1)}
_TO_GREY = {'rgb8': cv2.COLOR_RGB2GRAY, 'bgr8': cv2.COLOR_BGR2GRAY,
            'rgba8': cv2.COLOR_RGBA2GRAY, 'bgra8': cv2.COLOR_BGRA2GRAY,
            'bayer_rggb8': cv2.COLOR_BayerBG2GRAY, 'bayer_bggr8': cv2.COLOR_BayerRG2GRAY,
            'bayer_gbrg8': cv2.COLOR_BayerGR2GRAY, 'bayer_grbg8': cv2.COLOR_BayerGB2GRAY}


def unpack(data: bytes, encoding: str, width: int, height: int, step: int,
           big_endian: bool = False) -> tuple[np.ndarray | None, str]:
    """An Image message's fields -> (height, width[, channels]) array, or None and the reason."""
    if encoding not in LAYOUTS:
        return None, (f'unsupported image encoding {encoding!r} (supported: '
                      f'{", ".join(LAYOUTS)})')
    channels, depth = LAYOUTS[encoding]
    row = width * channels * depth
    if step < row or len(data) < step * height:
        return None, (f'image data of {len(data)} bytes does not hold {height} rows of step '
                      f'{step} >= {row} bytes')
    rows = np.frombuffer(data, np.uint8, count=step * height).reshape(height, step)[:, :row]
    dtype = np.dtype(np.uint16).newbyteorder('>' if big_endian else '<') if depth == 2 \
        else np.dtype(np.uint8)
    pixels = np.ascontiguousarray(rows).view(dtype).reshape(height, width, channels)
    return (pixels[:, :, 0] if channels == 1 else pixels), ''


def to_mono8(pixels: np.ndarray, encoding: str) -> np.ndarray:
    """An unpacked image of ``encoding`` -> (height, width) uint8 grey."""
    if encoding == 'mono16':
        return (pixels.astype(np.uint32) * 255 // 65535).astype(np.uint8)
    if encoding in _TO_GREY:
        return cv2.cvtColor(np.ascontiguousarray(pixels), _TO_GREY[encoding])
    return pixels


def image_to_array(msg: Any) -> tuple[np.ndarray | None, str]:
    """A sensor_msgs/Image -> (height, width) uint8 grey array, or None and the reason."""
    pixels, reason = unpack(bytes(msg.data), msg.encoding, msg.width, msg.height, msg.step,
                            bool(msg.is_bigendian))
    return (None, reason) if pixels is None else (to_mono8(pixels, msg.encoding), '')
