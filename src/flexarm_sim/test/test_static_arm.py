"""The arm without dynamics: moves arrive at once with the error sources' effect, time runs on,
measurements come through the true camera and the vision estimator."""
import copy

import numpy as np
import pytest

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_sim.errors import ArmErrors
from flexarm_sim.plant import Plant
from flexarm_sim.static_arm import StaticArm
from flexarm_sim.true_camera import true_renderer
from flexarm_vision.pose_estimator import TipPoseEstimator

START = np.array([0.0, 0.6, 0.0, 0.0])
POSE = np.array([-0.3, 0.6, -0.2, -0.1])


@pytest.fixture(scope='module')
def config():
    return {**load_config('arm.yaml', 'sim.yaml', 'camera.yaml'),
            **load_config('vision.yaml', node_name='flexarm_vision')}


def arm(config, on: bool, seed: int = 0) -> StaticArm:
    sources = copy.deepcopy(config['error_sources'])
    sources['enabled'] = on
    geometry = ArmGeometry.from_dict(config['arm'])
    plant = Plant.from_dict(config['plant'], geometry)
    return StaticArm(plant, ArmErrors.from_dict(sources, plant.backlash), START,
                     true_renderer(config, sources), TipPoseEstimator.from_dict(config),
                     np.random.default_rng(seed))


def test_the_ideal_arm_arrives_at_the_plant_pose_and_is_measured_there(config):
    a = arm(config, on=False)
    assert a.move(POSE, np.zeros(4), 10.0)
    np.testing.assert_array_equal(a.positions(), POSE)
    np.testing.assert_allclose(a.truth(), a.plant.pose(POSE), atol=1e-15)
    travel = np.max(np.abs(POSE - START) / a.plant.geometry.velocity)
    assert a.time == pytest.approx(travel + a.settle)
    measured = a.measure(3, 10.0)
    assert measured.frames == 3
    assert np.hypot(*(measured.pose[:2] - a.truth()[:2])) < 0.01e-3
    assert a.time == pytest.approx(travel + a.settle + 3 / a.frame_rate)


def test_with_the_sources_on_moves_scatter_and_the_camera_is_off(config):
    a = arm(config, on=True)
    tips = []
    for k in range(20):
        a.move(START if k % 2 else POSE, np.zeros(4), 10.0)
        if not k % 2:
            tips.append(a.truth())
    spread = np.std(np.array(tips)[:, :2], axis=0)
    assert 5e-6 < spread.max() < 1e-4              # repeatability: some 10 um at the tip
    truth = a.truth()
    error = a.measure(3, 10.0).pose - truth
    assert 0.1e-3 < np.hypot(*error[:2]) < 0.25e-3  # the true camera: principal point etc.
