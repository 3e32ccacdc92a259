"""Camera model geometry and the synthetic tip camera renderer."""
import copy

import cv2
import numpy as np
import pytest

from flexarm_core.params import load_config
from flexarm_sim.camera import CameraRenderer
from flexarm_vision.camera_model import CameraModel, rotation

CONFIG = load_config('camera.yaml')
POSE = np.array([1.2, -0.3, 0.7])


def camera_config(**changes: float) -> dict:
    config = copy.deepcopy(CONFIG)
    config['camera'].update(changes)
    return config


def plate_to_pixels(camera: CameraModel, points: np.ndarray, pose) -> np.ndarray:
    """Plate points (N, 2) [m] -> pixels (N, 2) for tip pose (x, y, phi), per the model."""
    q = (np.asarray(points, dtype=float) - camera.optical_centre(pose)) @ rotation(pose[2])
    return camera.metric_to_pixels(q)


@pytest.fixture(scope='module')
def renderer() -> CameraRenderer:
    return CameraRenderer.from_dict(CONFIG)


LENSES = [{}, {'k1': -0.08, 'k2': 0.02}, {'k1': 0.05},
          {'k1': -0.04, 'k2': 0.01, 'p1': 8e-4, 'p2': -5e-4, 'k3': 0.002}]


@pytest.mark.parametrize('lens', LENSES)
def test_pixel_metric_round_trip(lens: dict) -> None:
    camera = CameraModel.from_dict(camera_config(**lens)['camera'])
    pixels = np.random.default_rng(0).uniform([0, 0], [640, 480], size=(50, 2))
    metric = camera.pixels_to_metric(pixels)
    np.testing.assert_allclose(camera.metric_to_pixels(metric), pixels, atol=1e-6)


def test_the_lens_model_is_opencvs_plumb_bob() -> None:
    lens = LENSES[-1]
    camera = CameraModel.from_dict(camera_config(**lens)['camera'])
    i = camera.intrinsics
    metric = np.random.default_rng(1).uniform(-0.02, 0.02, size=(20, 2))
    points = np.column_stack([metric[:, 0], -metric[:, 1], np.full(20, camera.standoff)])
    k = np.array([[i.fx, 0, i.cx], [0, i.fy, i.cy], [0, 0, 1]])
    projected, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), k,
                                     np.array(i.distortion))
    np.testing.assert_allclose(camera.metric_to_pixels(metric), projected[:, 0], atol=1e-9)


@pytest.mark.parametrize('lens', LENSES)
def test_magnification_is_the_area_scale_of_the_lens(lens: dict) -> None:
    camera = CameraModel.from_dict(camera_config(**lens)['camera'])
    ideal = CameraModel.from_dict(CONFIG['camera'])
    metric = np.random.default_rng(2).uniform(-0.02, 0.02, size=(20, 2))
    step = 1e-7
    jacobian = np.stack([(camera.metric_to_pixels(metric + d) - camera.metric_to_pixels(
        metric - d)) / (2 * step) for d in (np.array([step, 0]), np.array([0, step]))], -1)
    area = np.abs(np.linalg.det(jacobian)) * camera.scale ** 2
    np.testing.assert_allclose(camera.magnification(metric) ** 2, area, rtol=1e-6)
    np.testing.assert_allclose(ideal.magnification(metric), 1.0)


def test_optical_axis_and_tip_point() -> None:
    camera = CameraModel.from_dict(CONFIG['camera'])
    i = camera.intrinsics
    for pose in ([1.2, -0.3, 0.7], [0.4, 0.5, -3.0], [1.8, -0.9, 2.2]):
        np.testing.assert_allclose(
            plate_to_pixels(camera, camera.optical_centre(pose)[None], pose), [[i.cx, i.cy]])
        # The tip itself is seen at a fixed pixel, whatever the pose: the offset is rigid.
        tip_pixel = plate_to_pixels(camera, np.array([pose[:2]]), pose)
        expected = [i.cx - camera.offset[0] / camera.scale, i.cy + camera.offset[1] / camera.scale]
        np.testing.assert_allclose(tip_pixel, [expected], atol=1e-9)
    np.testing.assert_allclose(camera.tip_from_camera(camera.optical_centre(POSE), POSE[2]), POSE)


def test_image_axes_follow_the_tool() -> None:
    camera = CameraModel.from_dict(CONFIG['camera'])
    centre = camera.optical_centre(POSE)
    along_tool = centre + 0.01 * np.array([np.cos(POSE[2]), np.sin(POSE[2])])
    left_of_tool = centre + 0.01 * np.array([-np.sin(POSE[2]), np.cos(POSE[2])])
    du, dv = plate_to_pixels(camera, np.array([along_tool, left_of_tool]), POSE) - [
        camera.intrinsics.cx, camera.intrinsics.cy]
    assert du[0] == pytest.approx(0.01 / camera.scale) and abs(du[1]) < 1e-9
    assert dv[1] == pytest.approx(-0.01 / camera.scale) and abs(dv[0]) < 1e-9


def test_intrinsics_in_plumb_bob_order() -> None:
    i = CameraModel.from_dict(camera_config(k1=-0.1, k2=0.02)['camera']).intrinsics
    assert i.distortion == (-0.1, 0.02, 0.0, 0.0, 0.0)
    assert (i.width, i.height) == (640, 480)


def test_render_is_mono8_and_shows_dark_holes(renderer: CameraRenderer) -> None:
    image = renderer.render(POSE, rng=np.random.default_rng(0))
    assert image.dtype == np.uint8 and image.shape == (480, 640)
    assert np.median(image) > 150 and image.min() < 60


def test_a_tenth_of_a_pixel_changes_the_image(renderer: CameraRenderer) -> None:
    base = renderer.render(POSE).astype(int)
    step = 0.1 * renderer.camera.scale
    for delta in ([step, 0, 0], [0, step, 0], [0, 0, 0.1 / 320]):
        moved = renderer.render(POSE + np.array(delta)).astype(int)
        assert np.abs(moved - base).sum() > 100


def test_noise_comes_from_the_generator(renderer: CameraRenderer) -> None:
    clean = renderer.render(POSE)
    assert np.array_equal(clean, renderer.render(POSE))
    a = renderer.render(POSE, rng=np.random.default_rng(5))
    b = renderer.render(POSE, rng=np.random.default_rng(5))
    assert np.array_equal(a, b) and not np.array_equal(a, clean)
    sigma = CONFIG['camera_render']['noise_sigma']
    assert np.std(a.astype(float) - clean) == pytest.approx(sigma, rel=0.2)


def blob_extents(image: np.ndarray) -> np.ndarray:
    """(width, height) [px] of the whole dark blobs, incl. their faint smear."""
    _, mask = cv2.threshold(image, 165, 1, cv2.THRESH_BINARY_INV)   # just below the plate
    _, _, stats, _ = cv2.connectedComponentsWithStats(mask)
    left, top, w, h, _ = stats[1:].T
    whole = (left > 0) & (top > 0) & (left + w < 640) & (top + h < 480)
    return np.column_stack([w, h])[whole]


def test_motion_blur_smears_the_holes_along_the_motion(renderer: CameraRenderer) -> None:
    pose = np.array([1.2, -0.3, 0.0])                # image u along base x
    exposure = CONFIG['camera_render']['exposure']
    smear = 0.3 * exposure / renderer.camera.scale   # [px]
    still = blob_extents(renderer.render(pose))
    moving = blob_extents(renderer.render(pose, tip_velocity=(0.3, 0.0, 0.0)))
    assert np.all(np.abs(still[:, 0] - still[:, 1]) <= 1)
    stretch = moving[:, 0] - moving[:, 1]
    # at ~20 % coverage the threshold sees about 60 % of the linear smear ramp
    assert np.all(stretch >= 1) and 0.3 * smear < np.mean(stretch) < smear + 1
    turning = renderer.render(pose, tip_velocity=(0.0, 0.0, 0.2))
    assert np.abs(turning.astype(int) - renderer.render(pose)).sum() > 1000


def test_render_refuses_bad_pose(renderer: CameraRenderer) -> None:
    with pytest.raises(ValueError):
        renderer.render([1.0, np.nan, 0.0])
    with pytest.raises(ValueError):
        renderer.render([1.0, 0.0])


def test_off_the_plate_is_blank(renderer: CameraRenderer) -> None:
    image = renderer.render([5.0, 5.0, 0.0])
    assert image.min() > 150
