"""Hole detection: sub-pixel centres, sizes, spurious blobs, holes cut by the border."""
import cv2
import numpy as np
import pytest

from flexarm_core.params import load_config
from flexarm_sim.camera import CameraRenderer
from flexarm_vision.camera_model import CameraModel, rotation
from flexarm_vision.hole_detector import DetectorSettings, HoleDetector

CONFIG = {**load_config('camera.yaml'), **load_config('vision.yaml', node_name='flexarm_vision')}
SETTINGS = DetectorSettings.from_dict(CONFIG['vision'])


def plate_to_pixels(camera: CameraModel, points: np.ndarray, pose) -> np.ndarray:
    """Plate points (N, 2) [m] -> pixels (N, 2) for tip pose (x, y, phi), per the model."""
    q = (np.asarray(points, dtype=float) - camera.optical_centre(pose)) @ rotation(pose[2])
    return camera.metric_to_pixels(q)


@pytest.fixture(scope='module')
def renderer() -> CameraRenderer:
    return CameraRenderer.from_dict(CONFIG)


@pytest.fixture(scope='module')
def detector(renderer: CameraRenderer) -> HoleDetector:
    scale = renderer.camera.scale
    return HoleDetector(SETTINGS, min(renderer.plate.diameters) / scale,
                        max(renderer.plate.diameters) / scale)


def visible_holes(renderer: CameraRenderer, pose: np.ndarray, margin: float) -> tuple:
    """Projected centres [px] and diameters [px] of holes at least ``margin`` px inside."""
    centre = renderer.camera.optical_centre(pose)
    index, centres = renderer.plate.holes_near(centre, 0.3)
    pixels = plate_to_pixels(renderer.camera, centres, pose)
    diameters = (np.array(renderer.plate.diameters)[renderer.plate.symbols[index[:, 0],
                                                                          index[:, 1]]]
                 / renderer.camera.scale)
    inside = ((pixels[:, 0] > margin + diameters / 2) & (pixels[:, 1] > margin + diameters / 2)
              & (pixels[:, 0] < 639 - margin - diameters / 2)
              & (pixels[:, 1] < 479 - margin - diameters / 2))
    return pixels[inside], diameters[inside]


def match(found: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Distance [px] from each true centre to the nearest found one."""
    return np.min(np.hypot(*(truth[:, None, :] - found[None, :, :]).transpose(2, 0, 1)), axis=1)


@pytest.mark.parametrize('seed', range(6))
def test_centres_and_sizes_of_noisy_images(renderer: CameraRenderer, detector: HoleDetector,
                                           seed: int) -> None:
    rng = np.random.default_rng(seed)
    pose = np.array([rng.uniform(0.6, 1.7), rng.uniform(-0.7, 0.4), rng.uniform(-np.pi, np.pi)])
    detection = detector.detect(renderer.render(pose, rng=rng))
    truth, diameters = visible_holes(renderer, pose, margin=SETTINGS.roi_margin + 2)
    assert detection.status == '' and len(truth) >= 12
    assert np.all(match(detection.centres, truth) < 0.05)          # sub-pixel: 0.05 px
    nearest = np.argmin(np.hypot(*(truth[:, None] - detection.centres[None]).transpose(2, 0, 1)),
                        axis=1)
    np.testing.assert_allclose(detection.diameters[nearest], diameters, atol=0.5)


def test_holes_cut_by_the_border_are_rejected(renderer: CameraRenderer,
                                              detector: HoleDetector) -> None:
    camera = renderer.camera
    pose = np.array([1.0, -0.2, 0.0])
    # Shift the view so that one hole centre lies exactly on the left image border.
    _, centres = renderer.plate.holes_near(camera.optical_centre(pose), 0.2)
    pixels = plate_to_pixels(camera, centres, pose)
    leftmost = pixels[np.argmin(np.abs(pixels[:, 0] - 20))]
    pose[0] += leftmost[0] * camera.scale
    detection = detector.detect(renderer.render(pose))
    all_pixels = plate_to_pixels(camera, centres, pose)
    on_border = all_pixels[np.abs(all_pixels[:, 0]) < 1e-6]
    assert len(on_border) >= 1
    assert np.all(match(detection.centres, on_border) > 5)
    assert np.all(detection.centres[:, 0] > SETTINGS.roi_margin)


def test_spurious_blobs_are_rejected(renderer: CameraRenderer, detector: HoleDetector) -> None:
    pose = np.array([1.3, 0.1, 1.0])
    image = renderer.render(pose, rng=np.random.default_rng(1))
    clean = detector.detect(image)
    cv2.line(image, (30, 200), (120, 230), 20, 3)                    # a scratch
    cv2.ellipse(image, (400, 60), (20, 6), 30, 0, 360, 20, -1)       # an elongated stain
    cv2.rectangle(image, (200, 400), (260, 440), 20, -1)             # a large dark patch
    cv2.circle(image, (600, 300), 2, 20, -1)                         # a speck of dust
    dirty = detector.detect(image)
    truth, _ = visible_holes(renderer, pose, margin=SETTINGS.roi_margin + 2)
    junk = np.array([[75, 215], [400, 60], [230, 420], [600, 300.0]])
    far = np.all(np.hypot(*(truth[:, None] - junk[None]).transpose(2, 0, 1)) > 40, axis=1)
    assert len(dirty.centres) <= len(clean.centres)
    assert np.all(match(dirty.centres, truth[far]) < 0.05)
    whole, _ = visible_holes(renderer, pose, margin=0)
    assert np.all(match(whole, dirty.centres) < 0.05)       # every detection is a true hole


@pytest.mark.parametrize('image, reason', [
    (np.zeros((480, 640), np.uint8), 'too dark'),
    (np.full((480, 640), 255, np.uint8), 'saturated'),
])
def test_dark_and_saturated_images_are_refused(detector: HoleDetector, image: np.ndarray,
                                               reason: str) -> None:
    detection = detector.detect(image)
    assert reason in detection.status and len(detection.centres) == 0


def test_noise_and_blank_images_have_no_holes(detector: HoleDetector) -> None:
    noise = np.random.default_rng(0).integers(0, 256, (480, 640), dtype=np.uint8)
    assert len(detector.detect(noise).centres) == 0
    assert len(detector.detect(np.full((480, 640), 180, np.uint8)).centres) == 0
