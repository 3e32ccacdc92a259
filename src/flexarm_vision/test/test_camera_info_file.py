"""The camera calibration as the YAML a ROS camera driver loads (camera_calibration_parsers'
format): every field the parser reads, with the intrinsics' values, the same numbers the
camera_info message of those intrinsics carries."""
from __future__ import annotations

from pathlib import Path

import yaml

from flexarm_vision.camera_info import camera_info
from flexarm_vision.camera_info_file import CAMERA_NAME, write_camera_info_file
from flexarm_vision.camera_model import Intrinsics

INTRINSICS = Intrinsics(width=640, height=480, fx=1732.4, fy=1730.9, cx=327.5, cy=233.0,
                        distortion=(-0.04, 0.01, 8e-4, -5e-4, 0.002))


def test_the_file_holds_every_field_of_the_format_with_the_intrinsics(tmp_path: Path) -> None:
    path = tmp_path / 'calibration' / 'camera_info.yaml'
    write_camera_info_file(path, INTRINSICS)
    assert [p.name for p in path.parent.iterdir()] == ['camera_info.yaml']   # atomic: no rest
    loaded = yaml.safe_load(path.read_text())
    assert list(loaded) == ['image_width', 'image_height', 'camera_name', 'camera_matrix',
                            'distortion_model', 'distortion_coefficients',
                            'rectification_matrix', 'projection_matrix']
    i = INTRINSICS
    assert (loaded['image_width'], loaded['image_height']) == (640, 480)
    assert loaded['camera_name'] == CAMERA_NAME
    assert loaded['distortion_model'] == 'plumb_bob'
    assert loaded['camera_matrix'] == {'rows': 3, 'cols': 3, 'data': [
        i.fx, 0.0, i.cx, 0.0, i.fy, i.cy, 0.0, 0.0, 1.0]}
    assert loaded['distortion_coefficients'] == {'rows': 1, 'cols': 5,
                                                 'data': list(i.distortion)}
    assert loaded['rectification_matrix'] == {'rows': 3, 'cols': 3, 'data': [
        1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]}
    assert loaded['projection_matrix'] == {'rows': 3, 'cols': 4, 'data': [
        i.fx, 0.0, i.cx, 0.0, 0.0, i.fy, i.cy, 0.0, 0.0, 0.0, 1.0, 0.0]}
    for field in ('camera_matrix', 'rectification_matrix', 'projection_matrix',
                  'distortion_coefficients'):
        matrix = loaded[field]
        assert len(matrix['data']) == matrix['rows'] * matrix['cols'], field


def test_it_says_what_the_camera_info_message_says(tmp_path: Path) -> None:
    write_camera_info_file(tmp_path / 'c.yaml', INTRINSICS, 'cam')
    loaded = yaml.safe_load((tmp_path / 'c.yaml').read_text())
    msg = camera_info(INTRINSICS)
    assert loaded['camera_name'] == 'cam'
    assert (loaded['image_width'], loaded['image_height']) == (msg.width, msg.height)
    assert loaded['distortion_model'] == msg.distortion_model
    for field, values in (('camera_matrix', msg.k), ('distortion_coefficients', msg.d),
                          ('rectification_matrix', msg.r), ('projection_matrix', msg.p)):
        assert loaded[field]['data'] == list(values), field
