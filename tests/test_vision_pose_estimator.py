"""Absolute tip pose from images: accuracy, full rotation range, plate code, bad input."""
import copy

import cv2
import numpy as np
import pytest

from flexarm_core.params import load_config
from flexarm_sim.camera import CameraRenderer
from flexarm_vision.plate import PlateLayout, design_code
from flexarm_vision.pose_estimator import TipPoseEstimator

CONFIG = {**load_config('camera.yaml'), **load_config('vision.yaml', node_name='flexarm_vision')}
POSITION_TOL = 0.05e-3      # [m]
ANGLE_TOL = np.radians(0.005)


def make(config: dict) -> tuple[CameraRenderer, TipPoseEstimator]:
    return CameraRenderer.from_dict(config), TipPoseEstimator.from_dict(config)


@pytest.fixture(scope='module')
def pair() -> tuple[CameraRenderer, TipPoseEstimator]:
    return make(CONFIG)


def assert_close(estimate, pose: np.ndarray) -> None:
    assert estimate.valid, estimate.status
    assert estimate.status == ''
    assert np.hypot(*(estimate.pose[:2] - pose[:2])) < POSITION_TOL
    assert abs(np.angle(np.exp(1j * (estimate.pose[2] - pose[2])))) < ANGLE_TOL
    assert -np.pi < estimate.pose[2] <= np.pi


def blocks_of(symbols: np.ndarray) -> list[bytes]:
    """Every 3x3 block of a code in each quarter-turn, as bytes (independent of plate.py)."""
    ni, nj = symbols.shape
    return [np.rot90(symbols[i:i + 3, j:j + 3], k).astype(np.int8).tobytes()
            for i in range(ni - 2) for j in range(nj - 2) for k in range(4)]


def test_configured_plate_code_is_unique_in_every_orientation() -> None:
    plate = PlateLayout.from_dict(CONFIG['plate'])
    blocks = blocks_of(plate.symbols)
    assert len(set(blocks)) == len(blocks)
    assert set(np.unique(plate.symbols)) == {0, 1, 2, 3}
    assert plate.centre(0, 0) == pytest.approx(CONFIG['plate']['origin'])


def test_designed_code_is_unique() -> None:
    blocks = blocks_of(design_code(12, 9, seed=1))
    assert len(set(blocks)) == len(blocks)


@pytest.mark.parametrize('seed', range(40))
def test_random_settled_poses(pair, seed: int) -> None:
    renderer, estimator = pair
    rng = np.random.default_rng(100 + seed)
    pose = np.array([rng.uniform(0.3, 1.9), rng.uniform(-1.0, 0.8), rng.uniform(-np.pi, np.pi)])
    estimate = estimator.estimate(renderer.render(pose, rng=rng))
    assert_close(estimate, pose)
    assert estimate.holes_used >= 12 and 0 < estimate.residual < 0.02e-3


def test_full_rotation_range(pair) -> None:
    renderer, estimator = pair
    rng = np.random.default_rng(7)
    for phi in np.linspace(-np.pi, np.pi, 37):
        pose = np.array([1.25, -0.15, phi])
        assert_close(estimator.estimate(renderer.render(pose, rng=rng)), pose)


def test_lens_distortion_is_undone() -> None:
    config = copy.deepcopy(CONFIG)
    config['camera'].update(k1=-0.08, k2=0.01)
    renderer, estimator = make(config)
    _, ideal = make(CONFIG)
    rng = np.random.default_rng(3)
    pose = np.array([0.9, 0.2, 2.0])
    image = renderer.render(pose, rng=rng)
    modelled, unmodelled = estimator.estimate(image), ideal.estimate(image)
    assert_close(modelled, pose)
    assert abs(modelled.radial) < 1e-3 and abs(modelled.scale - 1) < 1e-4
    # without the model, the fit sees the distortion as a radial stretch and still measures
    assert unmodelled.radial > 0.005 and unmodelled.residual > modelled.residual
    assert_close(unmodelled, pose)


@pytest.mark.parametrize('focal', [1.015, 0.985])
def test_a_camera_off_its_focal_length_still_measures_and_says_so(focal) -> None:
    true = copy.deepcopy(CONFIG)
    true['camera'].update(fx=CONFIG['camera']['fx'] * focal, fy=CONFIG['camera']['fy'] * focal)
    renderer, _ = make(true)
    _, estimator = make(CONFIG)                      # believes the calibrated focal length
    pose = np.array([1.2, -0.3, -1.1])
    estimate = estimator.estimate(renderer.render(pose, rng=np.random.default_rng(5)))
    assert_close(estimate, pose)
    assert estimate.scale == pytest.approx(focal, abs=1e-4)   # the plate seen larger/smaller


def test_a_camera_far_off_its_calibration_is_refused_with_the_reason() -> None:
    true = copy.deepcopy(CONFIG)
    true['camera'].update(standoff=CONFIG['camera']['standoff'] / 1.08)   # 8 % closer
    renderer, _ = make(true)
    _, estimator = make(CONFIG)
    estimate = estimator.estimate(renderer.render(np.array([1.2, -0.3, -1.1]),
                                                  rng=np.random.default_rng(5)))
    assert not estimate.valid
    assert estimate.status.startswith('plate seen +8.0 % off the scale of the camera')


def test_occluded_holes_and_dirt(pair) -> None:
    renderer, estimator = pair
    pose = np.array([1.1, -0.4, -2.5])
    image = renderer.render(pose, rng=np.random.default_rng(2))
    level = int(np.median(image))
    cv2.rectangle(image, (0, 0), (200, 479), level, -1)             # a third of the view hidden
    cv2.line(image, (300, 100), (420, 160), 10, 2)                  # a scratch
    cv2.circle(image, (500, 400), 3, 10, -1)                        # a speck
    assert_close(estimator.estimate(image), pose)


def test_partial_view_at_the_plate_edge(pair) -> None:
    renderer, estimator = pair
    plate = renderer.plate
    # Optical centre on the plate's left edge: half the view has no holes.
    edge_pose = np.array([plate.origin[0] - renderer.camera.offset[0], -0.2, 0.0])
    estimate = estimator.estimate(renderer.render(edge_pose, rng=np.random.default_rng(0)))
    assert_close(estimate, edge_pose)        # the visible half still holds whole 3x3 blocks
    off = estimator.estimate(renderer.render([plate.origin[0] - 0.2, -0.2, 0.0]))
    assert not off.valid and 'too few holes' in off.status and off.pose is None


def test_a_hole_of_unexpected_size_never_gives_a_wrong_pose(pair) -> None:
    renderer, estimator = pair
    pose = np.array([1.5, 0.3, 0.4])
    centre = renderer.camera.optical_centre(pose)
    index, _ = renderer.plate.holes_near(centre, 0.05)
    altered = copy.deepcopy(CONFIG)
    symbols = renderer.plate.symbols.copy()
    for i, j in index:                                   # repaint the central holes' sizes
        symbols[i, j] = (symbols[i, j] + 1) % 4
    rows = [''.join(str(s) for s in symbols[:, j]) for j in reversed(range(symbols.shape[1]))]
    altered['plate']['code'] = rows
    wrong_plate = CameraRenderer.from_dict(altered)
    estimate = estimator.estimate(wrong_plate.render(pose, rng=np.random.default_rng(4)))
    assert not estimate.valid and 'code' in estimate.status


@pytest.mark.parametrize('image, reason', [
    (np.zeros((480, 640), np.uint8), 'too dark'),
    (np.full((480, 640), 255, np.uint8), 'saturated'),
    (np.zeros((0, 0), np.uint8), 'expected a 640x480'),
    (np.zeros((480, 640), np.float32), 'uint8'),
    (np.zeros((480, 640), np.uint16), 'uint8'),
    (np.zeros((480, 640, 3), np.uint8), '2-D'),
    (np.zeros((240, 320), np.uint8), 'expected a 640x480'),
    (None, 'NoneType'),
    (b'\x00' * 10, 'bytes'),
    (np.full((480, 640), 180, np.uint8), 'too few holes'),
])
def test_bad_images_are_invalid_with_a_reason(pair, image, reason: str) -> None:
    estimate = pair[1].estimate(image)
    assert not estimate.valid and estimate.pose is None and reason in estimate.status


def test_noise_only_images_are_invalid(pair) -> None:
    rng = np.random.default_rng(0)
    for _ in range(5):
        noise = rng.integers(0, 256, (480, 640), dtype=np.uint8)
        estimate = pair[1].estimate(noise)
        assert not estimate.valid and estimate.status
    speckle = np.clip(rng.normal(180, 40, (480, 640)), 0, 255).astype(np.uint8)
    assert not pair[1].estimate(speckle).valid


def test_motion_smeared_image_is_not_trusted_blindly(pair) -> None:
    renderer, estimator = pair
    pose = np.array([1.0, -0.3, 0.3])
    image = renderer.render(pose, tip_velocity=(0.0, 0.0, 0.5), rng=np.random.default_rng(1))
    estimate = estimator.estimate(image)
    assert estimate.valid, estimate.status   # a smear about the mean pose measures the mean pose
    assert np.hypot(*(estimate.pose[:2] - pose[:2])) < 0.5e-3
    smeared = renderer.render(pose, tip_velocity=(2.0, 0.0, 0.0), rng=np.random.default_rng(1))
    assert not estimator.estimate(smeared).valid          # 8 mm of smear: holes unrecognisable
