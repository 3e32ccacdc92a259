"""A camera's calibration as the YAML file ROS camera drivers load (camera_calibration_parsers'
format, what ``camera_info_url`` points at), so that the intrinsics ``flexarm calibrate
--camera`` found can be given to the site's camera driver (pure)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from flexarm_core.atomic_file import atomic_write
from flexarm_vision.camera_model import Intrinsics

CAMERA_NAME = 'tip_camera'


def camera_info_dict(intrinsics: Intrinsics, camera_name: str = CAMERA_NAME) -> dict[str, Any]:
    """The file's fields: plumb_bob, no rectification (R identity, P = K | 0), as
    :func:`flexarm_vision.camera_info.camera_info` publishes the same intrinsics."""
    i = intrinsics

    def matrix(rows: int, cols: int, data: list[float]) -> dict[str, Any]:
        return {'rows': rows, 'cols': cols, 'data': [float(v) for v in data]}

    return {
        'image_width': i.width, 'image_height': i.height, 'camera_name': camera_name,
        'camera_matrix': matrix(3, 3, [i.fx, 0.0, i.cx, 0.0, i.fy, i.cy, 0.0, 0.0, 1.0]),
        'distortion_model': 'plumb_bob',
        'distortion_coefficients': matrix(1, len(i.distortion), list(i.distortion)),
        'rectification_matrix': matrix(3, 3, [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
        'projection_matrix': matrix(3, 4, [i.fx, 0.0, i.cx, 0.0, 0.0, i.fy, i.cy, 0.0,
                                           0.0, 0.0, 1.0, 0.0]),
    }


def write_camera_info_file(path: str | Path, intrinsics: Intrinsics,
                           camera_name: str = CAMERA_NAME) -> None:
    """Write :func:`camera_info_dict` to ``path`` as YAML, atomically."""
    text = yaml.safe_dump(camera_info_dict(intrinsics, camera_name), sort_keys=False,
                          default_flow_style=None, width=1 << 16)
    atomic_write(path, lambda f: f.write(text.encode()))
