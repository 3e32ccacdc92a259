"""The tool calibration as a frame: ``tip_link`` -> ``tip_camera_calibrated`` is the camera
where the correction puts it, so that a camera mounted there shows the vision node (through
the nominal mount) the very error the correction removes; neutral, it is the URDF's nominal
``tip_link`` -> ``tip_camera_link``."""
from __future__ import annotations

import math

import numpy as np
import pytest

from flexarm_core.frames import CALIBRATED_CAMERA_FRAME, TIP_FRAME
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_core.tool_correction import ToolCorrection
from flexarm_description.chain import CAMERA_FRAME, arm_joints, joint_transform
from flexarm_vision.camera_model import CameraModel
from flexarm_vision.vision_node import calibrated_mount

CAMERA = CameraModel.from_dict(load_config('camera.yaml')['camera'])
CORRECTION = ToolCorrection(axial=-1.3e-4, lateral=-1.0e-4, angle=math.radians(0.0206))


def as_tuples(msg) -> tuple[tuple[float, ...], tuple[float, ...]]:
    t, r = msg.transform.translation, msg.transform.rotation
    return (t.x, t.y, t.z), (r.x, r.y, r.z, r.w)


@pytest.mark.parametrize('tool', [[1.45, -0.15, -0.785], [1.0, -0.5, -1.745], [0.3, 0.4, 2.9]])
def test_a_camera_at_the_calibrated_mount_shows_the_error_the_correction_removes(tool) -> None:
    x, y, phi = tool
    along, across, angle = CORRECTION.camera_mount(CAMERA.offset)
    c, s = math.cos(phi), math.sin(phi)
    camera_at = np.array([x + c * along - s * across, y + s * along + c * across])
    measured = CAMERA.tip_from_camera(camera_at, phi + angle)      # the nominal mount
    np.testing.assert_allclose(CORRECTION.pose(measured), tool, atol=1e-12)
    assert not np.allclose(measured, tool, atol=1e-5)               # there was an error


def test_the_frame_is_the_planar_mount_in_3d() -> None:
    msg = calibrated_mount(CORRECTION, CAMERA.offset)
    assert (msg.header.frame_id, msg.child_frame_id) == (TIP_FRAME, CALIBRATED_CAMERA_FRAME)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (0, 0)
    along, across, angle = CORRECTION.camera_mount(CAMERA.offset)
    translation, rotation = as_tuples(msg)
    assert translation == pytest.approx((along, 0.0, across), abs=1e-15)
    # a turn of +angle about -y, as the revolute joints turn: the tool axis towards +z
    assert rotation == pytest.approx((0.0, -math.sin(angle / 2), 0.0, math.cos(angle / 2)))


def test_neutral_it_is_the_urdfs_nominal_camera() -> None:
    geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
    nominal = next(joint_transform(j) for j in arm_joints(geometry, CAMERA.offset)
                   if j.child == CAMERA_FRAME)
    translation, rotation = as_tuples(calibrated_mount(ToolCorrection(), CAMERA.offset))
    assert nominal.parent == TIP_FRAME
    assert translation == pytest.approx(nominal.translation, abs=1e-15)
    assert rotation == pytest.approx(nominal.rotation, abs=1e-15)
