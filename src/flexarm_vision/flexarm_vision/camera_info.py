"""A camera's intrinsics as a ROS ``sensor_msgs/CameraInfo`` and back (no rclpy): the simulator
publishes its camera's calibration with it, the vision node reads it and publishes the
intrinsics it uses."""
from __future__ import annotations

from sensor_msgs.msg import CameraInfo
from std_msgs.msg import Header

from flexarm_vision.camera_model import Intrinsics

DISTORTION_MODELS = ('plumb_bob', '')   # '' with an empty D: an ideal lens


def camera_info(intrinsics: Intrinsics, header: Header | None = None) -> CameraInfo:
    """The plumb_bob CameraInfo of ``intrinsics`` (no rectification: R identity, P = K)."""
    i = intrinsics
    return CameraInfo(header=header or Header(), width=i.width, height=i.height,
                      distortion_model='plumb_bob', d=list(i.distortion),
                      k=[i.fx, 0.0, i.cx, 0.0, i.fy, i.cy, 0.0, 0.0, 1.0],
                      r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                      p=[i.fx, 0.0, i.cx, 0.0, 0.0, i.fy, i.cy, 0.0, 0.0, 0.0, 1.0, 0.0])


def info_intrinsics(info: CameraInfo) -> tuple[Intrinsics | None, str]:
    """The intrinsics a camera_info publishes, or None and why they cannot be used."""
    if info.distortion_model not in DISTORTION_MODELS or (
            not info.distortion_model and len(info.d)):
        return None, (f'camera_info distortion model {info.distortion_model!r} is not '
                      'supported (plumb_bob only)')
    try:
        return Intrinsics.from_k_d(info.width, info.height, list(info.k), list(info.d)), ''
    except ValueError as exc:
        return None, f'camera_info not usable: {exc}'
