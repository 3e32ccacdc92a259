"""The grey-box predictor: compliances recovered from a known truth, payloads it never saw (also
from samples at one payload, against the simulated plant), the residual GP, self-contained
model files."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flexarm_control.learning.at_payload import AtPayload
from flexarm_control.learning.gravity_moments import ArmMasses
from flexarm_control.learning.models import load_model
from flexarm_control.learning.predictors import greybox, kinematic, make_predictor
from flexarm_control.learning.sampling import sample_poses
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_core.regions import regions_from_dict
from flexarm_sim.plant import Plant

LOWER = np.array([-0.6, 0.3, -1.6, -1.0])
UPPER = np.array([0.3, 0.8, 0.0, 1.0])
KINEMATIC = np.array([1.7e-4, 5e-4, -2.6e-4, 3.5e-4, 3e-4, -4e-4, 2e-4])
# [rad/(N·m), m/(N·m)]: about half of Table 5's, as the simulated arm
COMPLIANCE = {'joint1': 1e-5, 'guide2': 1.5e-5, 'joint3': 4e-5, 'arm3_deflection': 3.5e-5,
              'joint4': 2.4e-4, 'arm4_deflection': 3.4e-4, 'arm4_angle': 8e-4}


def random_joints(n: int, seed: int) -> np.ndarray:
    return LOWER + (UPPER - LOWER) * np.random.default_rng(seed).random((n, 4))


def truth(joints: np.ndarray, payload: np.ndarray | float = 0.0) -> np.ndarray:
    """Deflection of an arm with COMPLIANCE and KINEMATIC errors, written out here."""
    arm = greybox.load_arm()
    m1, m2, m3, m4 = arm.moments(joints, payload).T
    c = COMPLIANCE
    turns = np.column_stack([c['joint1'] * m1 + c['guide2'] * m2, c['joint3'] * m3,
                             c['joint4'] * m4, c['arm4_angle'] * m4])
    shifts = np.column_stack([np.zeros(len(m1)), c['arm3_deflection'] * m3,
                              c['arm4_deflection'] * m4])
    geometry = {'link3': arm.link3, 'link4': arm.link4, 'offset': arm.offset}
    return (kinematic.perturbed_pose(geometry, joints, KINEMATIC, turns, shifts)
            - kinematic.perturbed_pose(geometry, joints, np.zeros(kinematic.KINEMATIC)))


def test_moments_follow_the_masses() -> None:
    arm = greybox.load_arm()
    stretched = np.array([0.0, 0.6, 0.0, 0.0])     # arm horizontal along +x
    m = arm.moments(stretched, 0.0)
    assert np.all(m < 0) and m[0] < m[1] < m[2] < m[3]   # the farther out, the less load
    lever = np.array([1.4, 1.4, 0.8, 0.4])   # [m] tip beyond joint1, the guide, joint3, joint4
    np.testing.assert_allclose(arm.moments(stretched, 1.0) - m, -9.80665 * lever, atol=1e-12)
    hanging = np.array([-np.pi / 2, 0.6, 0.0, 0.0])   # pointing down: no moment at joint4
    assert abs(arm.moments(hanging, 2.0)[3]) < 1e-9
    assert ArmMasses.from_dict(arm.as_dict()) == arm


def test_recovers_the_compliances_and_predicts_an_unseen_payload() -> None:
    joints = random_joints(40, seed=1)
    payload = np.random.default_rng(2).choice([0.0, 1.0, 2.0], 40)
    model = make_predictor('greybox', {'residual': 'none', 'payload_input': True}).fit(
        joints, truth(joints, payload), payload)
    found = model.metadata['greybox']['compliance']
    for name in ('joint3', 'joint4', 'arm4_deflection', 'arm4_angle'):
        assert found[name] == pytest.approx(COMPLIANCE[name], rel=0.02), name
    query = random_joints(200, seed=3)
    heavy = truth(query, 5.0)
    assert np.abs(heavy - truth(query, 0.0))[:, 1].max() > 0.01        # 5 kg: > 10 mm more
    assert np.abs(model.predict(query, 5.0) - heavy).max() < 2e-6
    with pytest.raises(ValueError, match='payload'):
        model.predict(query)


def test_without_payload_input_the_moments_take_the_configured_payload() -> None:
    joints = random_joints(30, seed=4)
    model = make_predictor('greybox', {'residual': 'none', 'payload': 2.0}).fit(
        joints, truth(joints, 2.0))
    query = random_joints(100, seed=5)
    assert np.abs(model.predict(query) - truth(query, 2.0)).max() < 1e-6


CONFIG = load_config('arm.yaml', 'sim.yaml', 'learner.yaml', node_name='flexarm_compensator')


@pytest.fixture(scope='module')
def world() -> tuple[ArmGeometry, Plant, dict]:
    """The simulated arm's geometry, a plant with the masses the model knows (the robot
    description's nominal ones: the model's own structure is tested) and the regions."""
    geometry = ArmGeometry.from_dict(CONFIG['arm'])
    designed = Plant.from_dict({**CONFIG['plant'], **CONFIG['arm']['inertia']}, geometry)
    return geometry, designed, regions_from_dict(CONFIG['regions'])


def tip_error(predicted: np.ndarray, truth: np.ndarray) -> float:
    """Largest position error [m]."""
    return float(np.hypot(*(predicted - truth)[:, :2].T).max())


# Largest tip error [m] at 0, 2.5 and 5 kg after 20 samples at 0 kg (measured: A 0.0002,
# 0.0013, 0.0028 mm; B 0.047, 0.11, 0.22 mm). In B the moment about joint4 changes sign,
# where the plant's compliance does too (Table 5): one compliance per element averages the
# two, and the payload moves the moments to one side.
AT_ONE_PAYLOAD = {'A': (0.01e-3, 0.01e-3, 0.01e-3), 'B': (0.1e-3, 0.2e-3, 0.3e-3)}


def test_masses_off_the_nominal_ones_limit_what_one_payload_tells_of_another(world) -> None:
    """The simulated real arm's parts are 4.3 % heavier than the description says (cables and
    hoses): trained at 0 kg, the fitted compliances hold that error, and the exact payload
    moment is deflected by them too (measured: 1.01 mm at 5 kg in A, 0.66 mm in B, against
    0.003 and 0.23 mm with the masses known). Samples at both payloads remove it."""
    geometry, designed, regions = world
    real = Plant.from_dict(CONFIG['plant'], geometry)
    joints = sample_poses(geometry, regions['A'], 20, 'sobol', 0)[1]
    query = sample_poses(geometry, regions['A'], 200, 'random', 1)[1]
    one = make_predictor('greybox').fit(joints, real.deflection(joints), np.zeros(20))
    missed = tip_error(one.predict(query, 5.0), real.with_payload(5.0).deflection(query))
    assert 0.5e-3 < missed < 1.5e-3
    both = np.repeat([0.0, 5.0], 10)
    heavy = real.with_payload(5.0).deflection(joints)
    two = make_predictor('greybox', {'payload_input': True}).fit(
        joints, np.where(both[:, None] > 0, heavy, real.deflection(joints)), both)
    assert tip_error(two.predict(query, 2.5), real.with_payload(2.5).deflection(query)) < (
        0.1 * missed)


def test_the_masses_prior_bounds_what_one_payload_cannot_tell(world) -> None:
    """Trained at 0 kg on the real arm (parts 4.3 % over the nominal masses), the prior's std
    is nothing at the trained payload, grows with the payload asked, and its 95 % point covers
    the miss at 5 kg (about 1 mm, the test above); samples at a second payload remove it."""
    geometry, _, regions = world
    real = Plant.from_dict(CONFIG['plant'], geometry)
    joints = sample_poses(geometry, regions['A'], 20, 'sobol', 0)[1]
    query = sample_poses(geometry, regions['A'], 50, 'random', 1)[1]
    one = make_predictor('greybox').fit(joints, real.deflection(joints), np.zeros(20))
    assert not one.prior_std(query, 0.0).any()
    spread = [np.hypot(*one.prior_std(query, kg)[:, :2].T) for kg in (2.5, 5.0)]
    assert np.all(spread[1] > 1.9 * spread[0]) and np.all(spread[0] > 0)
    miss = np.hypot(*(one.predict(query, 5.0) - real.with_payload(5.0).deflection(query))[
        :, :2].T)
    assert np.all(1.96 * spread[1] > miss) and np.median(1.96 * spread[1]) < 10 * np.median(miss)
    both = np.repeat([0.0, 5.0], 10)
    two = make_predictor('greybox', {'payload_input': True}).fit(joints, np.where(
        both[:, None] > 0, real.with_payload(5.0).deflection(joints), real.deflection(joints)),
        both)
    assert not two.prior_std(query, 2.5).any()


def test_its_std_is_the_structures_and_the_residuals(
        with_residual: greybox.GreyboxPredictor) -> None:
    """Noisy samples: the parameters' covariance states a std about the size of the miss; the
    residual GP's adds to it."""
    joints, query = random_joints(40, seed=6), random_joints(200, seed=9)
    noisy = truth(joints) + np.random.default_rng(3).normal(0.0, 2e-5, (40, 3))
    plain = make_predictor('greybox', {'residual': 'none'}).fit(joints, noisy)
    std = np.hypot(*plain.deflection_std(query)[:, :2].T)
    miss = np.hypot(*(plain.predict(query) - truth(query))[:, :2].T)
    assert 0.3 < np.median(miss) / np.median(std) < 3
    assert np.all(with_residual.deflection_std(query) >= with_residual._residual.deflection_std(
        query) - 1e-15)


@pytest.mark.parametrize('region', ['A', 'B'])
def test_trained_at_one_payload_it_predicts_at_the_payload_it_is_asked(world, region) -> None:
    geometry, plant, regions = world
    joints = sample_poses(geometry, regions[region], 20, 'sobol', 0)[1]
    model = make_predictor('greybox').fit(joints, plant.deflection(joints), np.zeros(20))
    assert model.payload_physical and model.carries_payload
    assert not model.settings['payload_input']
    query = sample_poses(geometry, regions[region], 200, 'random', 1)[1]
    for kg, limit in zip((0.0, 2.5, 5.0), AT_ONE_PAYLOAD[region]):
        truth = plant.with_payload(kg).deflection(query)
        assert tip_error(AtPayload(model, kg).predict(query), truth) < limit, kg
        assert tip_error(model.predict(query, kg), truth) < limit, kg
    assert tip_error(plant.with_payload(5.0).deflection(query), plant.deflection(query)) > 0.01
    np.testing.assert_array_equal(model.predict(query), model.predict(query, 0.0))
    # the payload is no input: it does not count in the distance from the learned data
    assert AtPayload(model, 5.0).data_distance(query[0]) == model.data_distance(query[0])


def test_the_moments_take_the_payload_the_samples_carried(world, tmp_path: Path) -> None:
    geometry, plant, regions = world
    joints = sample_poses(geometry, regions['A'], 20, 'sobol', 0)[1]
    heavy = plant.with_payload(5.0)
    model = make_predictor('greybox', {'residual': 'none'}).fit(
        joints, heavy.deflection(joints), np.full(20, 5.0))
    assert model.metadata['greybox']['trained_payload'] == 5.0
    query = sample_poses(geometry, regions['A'], 100, 'random', 1)[1]
    assert tip_error(model.predict(query), heavy.deflection(query)) < 0.01e-3
    assert tip_error(model.predict(query, 0.0), plant.deflection(query)) < 0.01e-3
    model.save(tmp_path / 'heavy.npz')
    loaded = load_model(tmp_path / 'heavy.npz')
    assert loaded.payload_physical
    np.testing.assert_array_equal(loaded.predict(query, 2.5), model.predict(query, 2.5))


@pytest.mark.parametrize('payload_input', [False, True])
def test_a_model_saved_before_it_carried_the_payload(world, tmp_path: Path,
                                                     payload_input: bool) -> None:
    """Without the payload input such a model took ``payload`` for its moments whatever the
    samples carried: it predicts as trained; with it, the moments took the samples'."""
    geometry, plant, regions = world
    joints = sample_poses(geometry, regions['A'], 20, 'sobol', 0)[1]
    payload = np.repeat([0.0, 5.0], 10) if payload_input else np.zeros(20)
    model = make_predictor('greybox', {'residual': 'none', 'payload_input': payload_input}).fit(
        joints, np.where(payload[:, None] > 0, plant.with_payload(5.0).deflection(joints),
                         plant.deflection(joints)), payload)
    del model.metadata['greybox']['trained_payload']
    model.save(tmp_path / 'old.npz')
    old = load_model(tmp_path / 'old.npz')
    assert old.payload_physical == old.carries_payload == payload_input
    heavy = AtPayload(old, 5.0).predict(joints)
    np.testing.assert_array_equal(heavy, model.predict(joints, 5.0 if payload_input else 0.0))


@pytest.mark.parametrize('kind, settings, carries', [
    ('gp', {}, False), ('mlp', {'members': 2, 'max_iterations': 50}, False),
    ('rbf', {}, False), ('kinematic', {}, False), ('gp', {'payload_input': True}, True)])
def test_only_a_payload_input_makes_the_other_kinds_carry_the_payload(
        kind: str, settings: dict, carries: bool) -> None:
    joints = random_joints(30, seed=9)
    payload = np.repeat([0.0, 5.0], 15)
    model = make_predictor(kind, settings).fit(joints, truth(joints, payload), payload)
    assert not model.payload_physical and model.carries_payload == carries


@pytest.fixture(scope='module')
def with_residual() -> greybox.GreyboxPredictor:
    """Fitted on the truth plus a bump the structure cannot explain."""
    joints = random_joints(40, seed=6)
    return make_predictor('greybox').fit(joints, truth(joints) + bump(joints))


def bump(joints: np.ndarray) -> np.ndarray:
    return 1e-4 * np.column_stack([np.sin(3 * joints[:, 0]), np.cos(2 * joints[:, 2]),
                                   np.zeros(len(joints))])


def test_the_residual_gp_learns_what_the_structure_leaves(
        with_residual: greybox.GreyboxPredictor) -> None:
    joints = random_joints(40, seed=6)
    plain = make_predictor('greybox', {'residual': 'none'}).fit(joints, truth(joints)
                                                                 + bump(joints))
    query = random_joints(200, seed=7)
    target = truth(query) + bump(query)
    assert (np.abs(with_residual.predict(query) - target).mean()
            < 0.5 * np.abs(plain.predict(query) - target).mean())
    assert with_residual.position_std(query).shape == (200,)
    assert 0 < with_residual.position_std(query[0]) < 1e-4
    assert plain.position_std(query[0]) == 0.0


def test_saved_model_is_self_contained(with_residual: greybox.GreyboxPredictor,
                                      tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / 'greybox.npz'
    with_residual.save(path)

    def no_config() -> ArmMasses:
        raise AssertionError('a saved model must not read the config')

    monkeypatch.setattr(greybox, 'load_arm', no_config)
    loaded = load_model(path)
    assert type(loaded) is greybox.GreyboxPredictor
    assert loaded.metadata == with_residual.metadata
    assert loaded.metadata['greybox']['arm']['masses']['end_effector'] == 4.65   # nominal
    query = random_joints(50, seed=8)
    np.testing.assert_allclose(loaded.predict(query), with_residual.predict(query),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(loaded.position_std(query), with_residual.position_std(query),
                               rtol=1e-9)
    np.testing.assert_allclose(loaded.deflection_std(query),
                               with_residual.deflection_std(query), rtol=1e-9)
    np.testing.assert_allclose(loaded.prior_std(query, 3.0), with_residual.prior_std(query, 3.0),
                               rtol=1e-9)


@pytest.mark.parametrize('settings, match', [
    ({'residual': 'mlp'}, 'residual'), ({'dead_band': 0.0}, 'dead_band'),
    ({'residual_kernel': 'cubic'}, 'residual_kernel'), ({'payload': -1.0}, 'payload')])
def test_bad_settings(settings: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make_predictor('greybox', settings)
