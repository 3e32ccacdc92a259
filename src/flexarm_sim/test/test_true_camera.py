"""The true camera against its calibration: what the vision pipeline, believing
config/camera.yaml, measures in its images (config/sim.yaml error_sources.camera)."""
import copy

import numpy as np
import pytest

from flexarm_core.params import load_config
from flexarm_sim.camera import CameraRenderer
from flexarm_sim.true_camera import CameraErrors, true_renderer
from flexarm_vision.camera_model import CameraModel, rotation
from flexarm_vision.pose_estimator import TipPoseEstimator

CAMERA = {**load_config('camera.yaml'), **load_config('vision.yaml', node_name='flexarm_vision')}
SOURCES = load_config('sim.yaml')['error_sources']
ERRORS = SOURCES['camera']
BELIEVED = CameraModel.from_dict(CAMERA['camera'])
ESTIMATOR = TipPoseEstimator.from_dict(CAMERA)
RNG = np.random.default_rng(8)
POSES = [np.array([RNG.uniform(0.4, 1.8), RNG.uniform(-0.9, 0.7), RNG.uniform(-np.pi, np.pi)])
         for _ in range(6)]
NONE = {'focal_length': 0.0, 'principal_point': [0.0, 0.0], 'k1': 0.0, 'k2': 0.0,
        'mount_yaw': 0.0,
        'mount_offset': [0.0, 0.0], 'hole_sigma': 0.0}


def camera_sources(*keep: str, enabled: bool = True) -> dict:
    """error_sources with the master and camera switches on and only the ``keep`` errors
    (all of them when none is named) at their configured magnitudes."""
    d = copy.deepcopy(SOURCES)
    d['enabled'], d['camera']['enabled'] = True, enabled
    if keep:
        d['camera'].update({k: v for k, v in NONE.items() if k not in keep})
    return d


def measured_error(renderer: CameraRenderer, pose: np.ndarray) -> np.ndarray:
    """Measured minus true tip pose: position in the tool frame [m], angle [rad]."""
    estimate = ESTIMATOR.estimate(renderer.render(pose))
    assert estimate.valid, estimate.status
    d = estimate.pose - pose
    return np.array([*(rotation(pose[2]).T @ d[:2]), np.angle(np.exp(1j * d[2]))])


def predicted_pose(renderer: CameraRenderer, pose: np.ndarray) -> np.ndarray:
    """What the believed camera makes of the true holes at their true pixels, by geometry: a
    rigid fit of its metric points to the nominal plate (the estimator's fit, no images)."""
    centre = renderer.camera.optical_centre(pose)
    index, true = renderer.plate.holes_near(centre, 0.2)
    pixels = renderer.camera.metric_to_pixels(
        (true - centre) @ rotation(pose[2] + renderer.mount_yaw))
    i, margin = renderer.intrinsics, 15     # [px] holes whole in the image
    seen = np.all((pixels > margin) & (pixels < [i.width - 1 - margin, i.height - 1 - margin]),
                  axis=1)
    q = BELIEVED.pixels_to_metric(pixels[seen])
    p = ESTIMATOR.plate.centre(index[seen, 0], index[seen, 1])
    qc, pc = q - q.mean(axis=0), p - p.mean(axis=0)
    phi = np.arctan2(np.sum(qc[:, 0] * pc[:, 1] - qc[:, 1] * pc[:, 0]), np.sum(qc * pc))
    return BELIEVED.tip_from_camera(p.mean(axis=0) - rotation(phi) @ q.mean(axis=0), phi)


@pytest.mark.parametrize('sources', [{**SOURCES, 'enabled': False}, camera_sources(enabled=False)])
def test_with_the_source_off_the_camera_is_its_calibration(sources):
    assert CameraErrors.from_dict(sources) is None
    ideal, renderer = CameraRenderer.from_dict(CAMERA), true_renderer(CAMERA, sources)
    for pose in POSES:
        image = renderer.render(pose, rng=np.random.default_rng(1))
        np.testing.assert_array_equal(image, ideal.render(pose, rng=np.random.default_rng(1)))
        error = measured_error(renderer, pose)
        assert np.hypot(*error[:2]) < 5e-6 and abs(error[2]) < 2e-5


def test_a_principal_point_error_shifts_the_measured_tip():
    renderer = true_renderer(CAMERA, camera_sources('principal_point'))
    dcx, dcy = ERRORS['principal_point']
    scale = BELIEVED.standoff / BELIEVED.intrinsics.fx              # [m/px]
    for pose in POSES:           # the plate under the believed principal point is taken as
        np.testing.assert_allclose(measured_error(renderer, pose),   # the optical axis
                                   [-dcx * scale, dcy * scale, 0.0], atol=5e-6)


def test_a_mount_yaw_turns_the_measured_tool_angle():
    renderer = true_renderer(CAMERA, camera_sources('mount_yaw'))
    yaw, offset = ERRORS['mount_yaw'], BELIEVED.offset
    for pose in POSES:           # ... and swings the tip about the camera by yaw x offset
        np.testing.assert_allclose(measured_error(renderer, pose),
                                   [yaw * offset[1], -yaw * offset[0], yaw], atol=5e-6)


def test_the_plate_holes_are_off_by_their_fixed_random_errors():
    renderer = true_renderer(CAMERA, camera_sources('hole_sigma'))
    errors = renderer.plate.errors
    assert errors.std() == pytest.approx(ERRORS['hole_sigma'], rel=0.05)
    np.testing.assert_array_equal(true_renderer(CAMERA, camera_sources()).plate.errors, errors)
    assert not np.array_equal(renderer.render(POSES[0]),
                              CameraRenderer.from_dict(CAMERA).render(POSES[0]))
    i, j = 20, 30
    np.testing.assert_array_equal(renderer.plate.centre(i, j),
                                  ESTIMATOR.plate.centre(i, j) + errors[i, j])


def test_the_true_camera_is_off_by_the_expected_amount():
    """Every error at once (intrinsics, distortion, mount, holes): the pipeline measures what
    geometry predicts, some 0.16 mm and 0.02 deg off the truth."""
    renderer = true_renderer(CAMERA, camera_sources())
    i = renderer.intrinsics
    assert (i.fx, i.cx, i.cy, i.k1, i.distortion[1]) == pytest.approx(
        (BELIEVED.intrinsics.fx * (1 + ERRORS['focal_length']),
         BELIEVED.intrinsics.cx + ERRORS['principal_point'][0],
         BELIEVED.intrinsics.cy + ERRORS['principal_point'][1], ERRORS['k1'], ERRORS['k2']))
    for pose in POSES:
        estimate = ESTIMATOR.estimate(renderer.render(pose))
        assert estimate.valid, estimate.status
        predicted = predicted_pose(renderer, pose)
        assert np.hypot(*(predicted - pose)[:2]) > 0.1e-3
        assert predicted[2] - pose[2] == pytest.approx(ERRORS['mount_yaw'], abs=1e-4)  # holes
        np.testing.assert_allclose(estimate.pose[:2], predicted[:2], atol=15e-6)
        assert estimate.pose[2] == pytest.approx(predicted[2], abs=2e-5)
