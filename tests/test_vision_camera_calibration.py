"""The camera's own parameters from plate images: what the plate determines, and what not."""
import dataclasses
import json

import numpy as np
import pytest

from flexarm_core.paper import TABLE_10
from flexarm_core.params import load_config
from flexarm_sim.camera import CameraRenderer
from flexarm_vision.camera_calibration import (
    CameraCorrection,
    calibrate_camera,
    read_camera_calibration,
    write_camera_calibration,
)
from flexarm_vision.camera_model import CameraModel
from flexarm_vision.pose_estimator import Estimate, TipPoseEstimator

CONFIG = {**load_config('camera.yaml'), **load_config('vision.yaml', node_name='flexarm_vision')}
ESTIMATOR = TipPoseEstimator.from_dict(CONFIG)
TARGETS = [t.pose for t in TABLE_10]


def true_camera(focal: float, k1: float, k2: float, cx: float = 0.0) -> CameraRenderer:
    """A renderer whose camera differs from the estimator's calibration."""
    renderer = CameraRenderer.from_dict(CONFIG)
    i = renderer.camera.intrinsics
    camera = CameraModel(dataclasses.replace(i, fx=i.fx * focal, fy=i.fy * focal, cx=i.cx + cx,
                                             distortion=(k1, k2, 0.0, 0.0, 0.0)),
                         renderer.camera.standoff, renderer.camera.offset)
    return CameraRenderer(renderer.plate, camera, renderer.settings)


def views(renderer: CameraRenderer, targets=TARGETS) -> tuple[list, list[float]]:
    rng = np.random.default_rng(3)
    matched = [(ESTIMATOR.match(renderer.render(t, rng=rng)), t[2]) for t in targets]
    assert not any(isinstance(m, Estimate) for m, _ in matched)
    return [m for m, _ in matched], [angle for _, angle in matched]


def test_the_plate_gives_focal_length_over_stand_off_and_the_radial_distortion() -> None:
    renderer = true_camera(1.006, -0.03, 0.01, cx=1.5)
    found = calibrate_camera(ESTIMATOR.camera, *views(renderer))
    c = found.correction
    assert c.focal_scale == pytest.approx(1.006, abs=5e-5)
    assert (c.k1, c.k2) == pytest.approx((-0.03, 0.01), abs=2e-3)
    assert found.views == 6 and found.holes > 6 * 9
    assert found.rms_after_px < 0.1 < found.rms_before_px
    assert 'principal point' in found.not_determined and 'k1' in found.determined
    corrected = ESTIMATOR.with_camera(ESTIMATOR.camera.with_intrinsics(
        c.apply(ESTIMATOR.camera.intrinsics)))
    estimate = corrected.estimate(renderer.render(TARGETS[0]))
    assert estimate.valid and abs(estimate.scale - 1) < 2e-4 and abs(estimate.radial) < 5e-4


def test_a_camera_as_calibrated_needs_no_correction() -> None:
    c = calibrate_camera(ESTIMATOR.camera, *views(CameraRenderer.from_dict(CONFIG))).correction
    assert c.focal_scale == pytest.approx(1.0, abs=5e-5)
    assert (c.k1, c.k2) == pytest.approx((0.0, 0.0), abs=2e-3)


def test_too_few_views_or_one_tool_angle_cannot_calibrate() -> None:
    matched, angles = views(CameraRenderer.from_dict(CONFIG), TARGETS[:3])
    with pytest.raises(ValueError, match='only 2 images of the plate decoded'):
        calibrate_camera(ESTIMATOR.camera, matched[:2], angles[:2])
    with pytest.raises(ValueError, match='span 0.0 deg of tool angle'):
        calibrate_camera(ESTIMATOR.camera, matched, [0.3, 0.3, 0.3])


def test_a_correction_changes_the_calibration_it_is_applied_to() -> None:
    i = ESTIMATOR.camera.intrinsics
    changed = CameraCorrection(1.01, -0.02, 0.005).apply(
        dataclasses.replace(i, distortion=(0.1, 0.2, 0.001, 0.002, 0.003)))
    assert (changed.fx, changed.fy, changed.cx) == pytest.approx((i.fx * 1.01, i.fy * 1.01, i.cx))
    assert changed.distortion == pytest.approx((0.08, 0.205, 0.001, 0.002, 0.003))
    assert CameraCorrection().apply(i) == i
    both = CameraCorrection(1.01, -0.02, 0.005) + CameraCorrection(0.99, 0.01, -0.001)
    assert both.as_list() == pytest.approx([1.01 * 0.99, -0.01, 0.004])
    for bad in ([1.0, 0.0], [1.0, float('nan'), 0.0], [3.0, 0.0, 0.0]):
        with pytest.raises(ValueError):
            CameraCorrection.from_list(bad)


def test_the_calibration_file_round_trips_and_a_damaged_one_names_itself(tmp_path) -> None:
    path = tmp_path / 'camera.json'
    assert read_camera_calibration(path) is None
    write_camera_calibration(path, CameraCorrection(1.002, -0.01, 0.0), views=6)
    record = read_camera_calibration(path)
    assert record['correction'] == CameraCorrection(1.002, -0.01, 0.0) and record['views'] == 6
    path.write_text(json.dumps({'camera_correction': [1.0]}))
    with pytest.raises(ValueError, match=f'camera calibration {path} is damaged'):
        read_camera_calibration(path)
