"""Kinematic calibration as a predictor: identified parameters, self-contained model files."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flexarm_deflection.models import load_model
from flexarm_deflection.predictors import kinematic, make_predictor

LOWER = np.array([-0.6, 0.3, -1.6, -1.0])
UPPER = np.array([0.3, 0.8, 0.0, 1.0])
TRUE = np.array([1.7e-4, 5e-4, -2.6e-4, 3.5e-4, 3e-4, -4e-4, 2e-4])   # PARAMETERS


def random_joints(n: int, seed: int) -> np.ndarray:
    return LOWER + (UPPER - LOWER) * np.random.default_rng(seed).random((n, 4))


def deflection(joints: np.ndarray, parameters: np.ndarray = TRUE) -> np.ndarray:
    geometry = kinematic.nominal_geometry()
    return (kinematic.perturbed_pose(geometry, joints, parameters)
            - kinematic.perturbed_pose(geometry, joints, np.zeros(kinematic.KINEMATIC)))


@pytest.fixture(scope='module')
def fitted() -> kinematic.KinematicPredictor:
    joints = random_joints(30, seed=1)
    return make_predictor('kinematic').fit(joints, deflection(joints))


def test_recovers_zero_offsets_and_link_errors(fitted: kinematic.KinematicPredictor) -> None:
    found = fitted.metadata['kinematic']['parameters']
    assert list(found) == list(kinematic.PARAMETERS)
    np.testing.assert_allclose(list(found.values()), TRUE, rtol=0, atol=1e-7)
    query = random_joints(200, seed=2)
    assert np.abs(fitted.predict(query) - deflection(query)).max() < 1e-7
    assert fitted.predict(query[0]).shape == (3,)


def test_the_rigid_pose_of_perturbed_pose_is_the_arm_model() -> None:
    from flexarm_core.kinematics import ArmGeometry, forward
    from flexarm_core.params import load_config

    joints = random_joints(20, seed=3)
    pose = kinematic.perturbed_pose(kinematic.nominal_geometry(), joints,
                                    np.zeros(kinematic.KINEMATIC))
    np.testing.assert_allclose(
        pose, forward(ArmGeometry.from_dict(load_config('arm.yaml')['arm']), joints),
        rtol=0, atol=1e-12)


def test_pose_jacobian_is_the_derivative_of_perturbed_pose() -> None:
    geometry, joints = kinematic.nominal_geometry(), random_joints(6, seed=10)
    rng = np.random.default_rng(11)
    # kinematic errors, then per sample 4 turns and 3 shifts
    parameters = np.concatenate([TRUE, rng.normal(0.0, 0.01, 6 * 7)])

    def split(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        turns, shifts = np.split(p[kinematic.KINEMATIC:].reshape(6, 7), [4], axis=1)
        return p[:kinematic.KINEMATIC], turns, shifts

    jacobian = kinematic.pose_jacobian(geometry, joints, *split(parameters))
    step = 1e-7
    for i in range(kinematic.KINEMATIC + 7):     # a kinematic error, or a turn or shift
        change = np.zeros_like(parameters)
        if i < kinematic.KINEMATIC:
            change[i] = step
        else:
            change[kinematic.KINEMATIC:].reshape(6, 7)[:, i - kinematic.KINEMATIC] = step
        numeric = (kinematic.perturbed_pose(geometry, joints, *split(parameters + change))
                   - kinematic.perturbed_pose(geometry, joints, *split(parameters - change))
                   ) / (2 * step)
        np.testing.assert_allclose(jacobian[:, :, i], numeric, rtol=0, atol=1e-8)


def test_noisy_samples_give_a_close_calibration() -> None:
    joints = random_joints(40, seed=4)
    noisy = deflection(joints) + np.random.default_rng(5).normal(0.0, 2e-5, (40, 3))
    model = make_predictor('kinematic').fit(joints, noisy)
    query = random_joints(200, seed=6)
    assert np.abs(model.predict(query) - deflection(query)).max() < 5e-5


def test_its_std_grows_with_the_noise_and_the_distance_and_matches_the_miss() -> None:
    """The identified parameters' covariance: noisier samples, or a query far from them,
    state a larger std; on noisy samples it is the size of the true miss."""
    joints, query = random_joints(40, seed=4), random_joints(200, seed=6)
    rng = np.random.default_rng(5)
    fits = {sigma: make_predictor('kinematic').fit(
        joints, deflection(joints) + rng.normal(0.0, sigma, (40, 3))) for sigma in (1e-6, 2e-5)}
    quiet, noisy = (np.hypot(*m.deflection_std(query)[:, :2].T) for m in fits.values())
    assert np.all(noisy > 5 * quiet)
    miss = np.hypot(*(fits[2e-5].predict(query) - deflection(query))[:, :2].T)
    assert 0.3 < np.median(miss) / np.median(noisy) < 3
    far = fits[2e-5].deflection_std(UPPER + 0.5 * (UPPER - LOWER))
    assert np.hypot(far[0], far[1]) > np.median(noisy) and far.shape == (3,)


def test_saved_model_is_self_contained(fitted: kinematic.KinematicPredictor, tmp_path: Path,
                                      monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / 'kinematic.npz'
    fitted.save(path)

    def no_config() -> dict[str, float]:
        raise AssertionError('a saved model must not read config/arm.yaml')

    monkeypatch.setattr(kinematic, 'nominal_geometry', no_config)
    loaded = load_model(path)
    assert type(loaded) is kinematic.KinematicPredictor
    assert loaded.metadata == fitted.metadata
    assert loaded.metadata['kinematic']['geometry'] == {'link3': 0.4, 'link4': 0.4,
                                                       'offset': 0.015}
    query = random_joints(50, seed=7)
    np.testing.assert_allclose(loaded.predict(query), fitted.predict(query), rtol=0, atol=1e-15)
    np.testing.assert_allclose(loaded.deflection_std(query), fitted.deflection_std(query))
    assert loaded.data_distance(query[0]) < loaded.data_distance(UPPER + (UPPER - LOWER))


def test_payload_is_accepted_and_changes_nothing() -> None:
    joints = random_joints(20, seed=8)
    model = make_predictor('kinematic', {'payload_input': True}).fit(
        joints, deflection(joints), np.linspace(0.0, 2.0, 20))
    np.testing.assert_array_equal(model.predict(joints, 0.0), model.predict(joints, 5.0))
    with pytest.raises(ValueError, match='payload'):
        model.predict(joints)


def test_bad_settings_and_data() -> None:
    with pytest.raises(ValueError, match='ridge'):
        make_predictor('kinematic', {'ridge': -1.0})
    model = make_predictor('kinematic')
    joints = random_joints(10, seed=9)
    with pytest.raises(RuntimeError, match='not fitted'):
        model.predict(joints)
    bad = deflection(joints)
    bad[3, 0] = np.nan
    with pytest.raises(ValueError, match='NaN'):
        model.fit(joints, bad)
