"""Deflection predictors: accuracy on a known function, determinism, persistence, errors."""
from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

from flexarm_deflection.models import load_model
from flexarm_deflection.predictors import Predictor, base, make_predictor

if TYPE_CHECKING:
    from sklearn.gaussian_process.kernels import Kernel

# The learned kinds, on the normalised space; the ones that model the arm (kinematic, greybox)
# and auto have tests of their own (test_<kind>_predictor.py).
KINDS = ('mlp', 'rbf', 'gp')

LOWER = np.array([-0.5, 0.3, -1.5, -1.0])
UPPER = np.array([0.5, 0.8, 0.5, 1.0])


def sag(joints: np.ndarray, payload: np.ndarray | float = 0.0) -> np.ndarray:
    """A smooth sag-like deflection (dx, dy [m] up to ~20 mm, dφ [rad] up to ~1.5°)."""
    t1, t2, t3, t4 = np.asarray(joints).T
    a3, a4 = t1 + t3, t1 + t3 + t4
    s = t2 / 0.6 * (1.0 + 0.5 * np.asarray(payload))
    return np.column_stack([
        0.006 * np.sin(t1) * np.cos(a3) * s,
        -0.012 * (0.5 + 0.5 * np.cos(t1) ** 2) * s ** 2 - 0.003 * np.cos(a4),
        -0.02 * np.cos(a3) * s - 0.01 * np.sin(a4)])


def random_joints(n: int, seed: int) -> np.ndarray:
    return LOWER + (UPPER - LOWER) * np.random.default_rng(seed).random((n, 4))


@pytest.fixture(scope='module')
def fitted() -> dict[str, Predictor]:
    joints = random_joints(60, seed=1)
    return {kind: make_predictor(kind).fit(joints, sag(joints)) for kind in KINDS}


@pytest.mark.parametrize('kind', KINDS)
def test_learns_a_smooth_function(fitted: dict[str, Predictor], kind: str) -> None:
    joints = random_joints(300, seed=2)
    truth = sag(joints)
    errors = np.abs(fitted[kind].predict(joints) - truth)
    spread = truth.max(axis=0) - truth.min(axis=0)
    assert np.all(errors.mean(axis=0) < 0.03 * spread), errors.mean(axis=0) / spread
    assert np.all(errors.max(axis=0) < 0.3 * spread), errors.max(axis=0) / spread
    np.testing.assert_allclose(fitted[kind].predict(joints[7]), fitted[kind].predict(joints)[7],
                               rtol=0, atol=1e-12)
    assert fitted[kind].predict(joints[7]).shape == (3,)


@pytest.mark.parametrize('kind', KINDS)
def test_deterministic_for_a_seed(fitted: dict[str, Predictor], kind: str) -> None:
    joints = random_joints(60, seed=1)
    again = make_predictor(kind).fit(joints, sag(joints))
    query = random_joints(20, seed=3)
    np.testing.assert_array_equal(again.predict(query), fitted[kind].predict(query))


def test_mlp_fit_is_deterministic_for_a_seed_and_the_seed_changes_it() -> None:
    joints, query = random_joints(30, seed=1), random_joints(20, seed=3)
    settings = {'members': 3, 'max_iterations': 50}
    a, again, b = (make_predictor('mlp', {**settings, 'seed': seed}).fit(joints, sag(joints))
                   for seed in (1, 1, 2))
    np.testing.assert_array_equal(again.predict(query), a.predict(query))
    np.testing.assert_array_equal(again.deflection_std(query), a.deflection_std(query))
    assert not np.array_equal(a.predict(query), b.predict(query))
    assert not np.array_equal(a.deflection_std(query), b.deflection_std(query))


@pytest.mark.parametrize('activation', ['tanh', 'sigmoid', 'relu', 'softplus'])
def test_mlp_predicts_with_the_network_it_trains(activation: str) -> None:
    """The numpy ensemble the model predicts with is the torch one training optimised."""
    import torch

    from flexarm_deflection.predictors import mlp

    rng = np.random.default_rng(0)
    x = rng.normal(size=(20, 4))
    layers = [(w * 3.0, rng.normal(size=b.shape))       # weights large enough to saturate
              for w, b in mlp.initial_layers([4, 6, 5, 3], 3, rng)]
    parameters = [torch.tensor(array) for layer in layers for array in layer]
    trained = mlp.torch_forward(parameters, activation, torch.tensor(x)).numpy()
    assert trained.shape == (3, 20, 3)
    np.testing.assert_allclose(mlp.forward(layers, activation, x), trained, rtol=0, atol=1e-12)


def test_mlp_ensemble_spread_grows_away_from_the_data(fitted: dict[str, Predictor]) -> None:
    model, train = fitted['mlp'], random_joints(60, seed=1)
    near = model.deflection_std(train)
    far = model.deflection_std(train + np.array([2.0, 0.5, 2.0, 2.0]))
    assert near.shape == far.shape == (60, 3) and model.deflection_std(train[0]).shape == (3,)
    np.testing.assert_allclose(model.deflection_std(train[0]), near[0], rtol=1e-12)
    assert np.all(near > 0)                 # the members disagree even where they were trained
    assert np.all(far.mean(axis=0) > 10 * near.mean(axis=0))
    assert np.all(far.min(axis=0) > near.max(axis=0))


def test_every_mlp_member_learns_the_function(fitted: dict[str, Predictor]) -> None:
    """The members are trained networks in their own right, and differ."""
    from flexarm_deflection.predictors import mlp

    model, joints = fitted['mlp'], random_joints(300, seed=2)
    normalisation = model._normalisation
    members = normalisation.outputs_back(mlp.forward(
        model._layers, 'tanh', normalisation.inputs(base.model_inputs(joints))))
    assert members.shape == (5, 300, 3)
    truth = sag(joints)
    errors = np.abs(members - truth).max(axis=1) / (truth.max(axis=0) - truth.min(axis=0))
    assert np.all(errors < 0.3), errors
    np.testing.assert_allclose(members.mean(axis=0), model.predict(joints), rtol=0, atol=1e-15)
    assert all(not np.allclose(members[0], other, rtol=0, atol=1e-6) for other in members[1:])


def _scikit_learn_kernel(kernel: str, inputs: int) -> Kernel:
    """The kernel of the GP's docstring as scikit-learn builds it, with the GP's defaults."""
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Matern, WhiteKernel

    bounds = np.tile([1e-2, 1e3], (inputs, 1))
    scales = np.ones(inputs)
    shape = {'rbf': RBF(scales, bounds), 'matern52': Matern(scales, bounds, nu=2.5),
             'matern32': Matern(scales, bounds, nu=1.5),
             'rbf+matern32': RBF(scales, bounds) + ConstantKernel(0.3, (1e-4, 1e1)) * Matern(
                 scales, bounds, nu=1.5)}[kernel]
    return ConstantKernel(1.0, (1e-3, 1e3)) * shape + WhiteKernel(1e-4, (1e-6, 1e-1))


@pytest.mark.parametrize('kernel', ['rbf', 'matern52', 'matern32', 'rbf+matern32'])
def test_gp_is_scikit_learns(kernel: str) -> None:
    from sklearn.gaussian_process import GaussianProcessRegressor

    from flexarm_learning.ard_gp import negative_log_likelihood

    joints = random_joints(30, seed=14)
    gp = make_predictor('gp', {'kernel': kernel, 'restarts': 1}).fit(joints, sag(joints))
    reference = _scikit_learn_kernel(kernel, gp._gp.x.shape[1])
    theta0, bounds = gp._hyperparameters(gp._gp.x.shape[1])
    np.testing.assert_allclose(theta0, reference.theta, rtol=1e-12)
    np.testing.assert_allclose(bounds, reference.bounds, rtol=1e-12)
    squares = (gp._gp.x[:, None] - gp._gp.x[None]) ** 2
    query = random_joints(40, seed=15)
    inputs = gp._normalisation.inputs(base.model_inputs(query))
    for k, theta in enumerate(gp._gp.theta):
        sklearn_gp = GaussianProcessRegressor(reference.clone_with_theta(theta),
                                              optimizer=None).fit(gp._gp.x, gp._gp.y[:, k])
        for probe in (theta, 0.5 * theta0 + 0.5 * theta):
            value, gradient = negative_log_likelihood(probe, kernel, squares, gp._gp.y[:, k])
            expected, expected_gradient = sklearn_gp.log_marginal_likelihood(
                probe, eval_gradient=True)
            assert value == pytest.approx(-expected, rel=1e-10)
            np.testing.assert_allclose(gradient, -expected_gradient, rtol=1e-8, atol=1e-7)
        mean, std = sklearn_gp.predict(inputs, return_std=True)
        np.testing.assert_allclose(gp._predict_normalised(inputs)[:, k], mean, rtol=0,
                                   atol=1e-9)
        np.testing.assert_allclose(gp.deflection_std(query)[:, k],
                                   std * gp._normalisation.output_std[k], rtol=1e-6)


@pytest.mark.parametrize('kind', KINDS)
def test_save_load_round_trip(fitted: dict[str, Predictor], kind: str, tmp_path: Path) -> None:
    path = tmp_path / 'models' / f'{kind}.npz'
    fitted[kind].save(path)
    loaded = load_model(path)
    assert type(loaded) is type(fitted[kind])
    assert loaded.metadata == fitted[kind].metadata
    assert loaded.metadata['kind'] == kind and loaded.metadata['samples'] == 60
    query = random_joints(50, seed=4)
    np.testing.assert_allclose(loaded.predict(query), fitted[kind].predict(query),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(loaded.deflection_std(query), fitted[kind].deflection_std(query),
                               rtol=0, atol=1e-12)
    assert os.listdir(path.parent) == [path.name]


def test_failed_save_keeps_the_old_file(fitted: dict[str, Predictor], tmp_path: Path,
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / 'model.npz'
    fitted['rbf'].save(path)
    before = path.read_bytes()

    def disk_full(file, **arrays) -> None:  # noqa: ANN001
        file.write(b'PK\x03\x04 half an archive')
        raise OSError('No space left on device')

    monkeypatch.setattr(base.np, 'savez', disk_full)
    with pytest.raises(OSError, match='No space'):
        fitted['mlp'].save(path)
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ['model.npz']
    assert load_model(path).kind == 'rbf'


def _rewrite(path: Path, change) -> None:  # noqa: ANN001
    """Rewrite the model file at ``path`` with ``change(entries)`` applied to its entries."""
    with np.load(path) as archive:
        entries = {name: archive[name] for name in archive.files}
    change(entries)
    np.savez(path, **entries)


DAMAGES = {
    'empty': lambda path: path.write_bytes(b''),
    'truncated': lambda path: path.write_bytes(path.read_bytes()[:path.stat().st_size // 2]),
    'foreign': lambda path: path.write_text('shopping list'),
    'no metadata': lambda path: _rewrite(path, lambda e: e.pop('metadata')),
    'metadata not an object': lambda path: _rewrite(
        path, lambda e: e.update(metadata=np.array('[1, 2]'))),
    'missing weights': lambda path: _rewrite(path, lambda e: e.pop('mlp.bias1')),
    'weights of the wrong shape': lambda path: _rewrite(
        path, lambda e: e.update({'mlp.weight0': np.zeros((10, 3))})),
    'fewer members than its settings': lambda path: _rewrite(
        path, lambda e: e.update({k: v[:-1] for k, v in e.items() if k.startswith('mlp.')})),
}


@pytest.mark.parametrize('damage', DAMAGES)
def test_damaged_model_file_raises_value_error(fitted: dict[str, Predictor], damage: str,
                                               tmp_path: Path) -> None:
    path = tmp_path / 'model.npz'
    fitted['mlp'].save(path)
    DAMAGES[damage](path)
    with pytest.raises(ValueError, match='model.npz'):
        load_model(path)


def test_gp_predictive_std(fitted: dict[str, Predictor]) -> None:
    gp = fitted['gp']
    train = random_joints(60, seed=1)
    far = train + np.array([2.0, 0.5, 2.0, 2.0])
    near_std, far_std = gp.deflection_std(train), gp.deflection_std(far)
    assert near_std.shape == far_std.shape == (60, 3)
    assert np.all(near_std > 0) and np.all(far_std.mean(axis=0) > 10 * near_std.mean(axis=0))
    assert gp.deflection_std(train[0]).shape == (3,)


def test_payload_as_input() -> None:
    joints = random_joints(80, seed=5)
    payload = np.random.default_rng(6).uniform(0.0, 2.0, 80)
    model = make_predictor('rbf', {'payload_input': True}).fit(
        joints, sag(joints, payload), payload)
    query = random_joints(100, seed=7)
    light, heavy = model.predict(query, 0.2), model.predict(query, np.full(100, 1.8))
    errors = np.abs(heavy - sag(query, 1.8))
    assert errors[:, 1].mean() < 0.1 * np.abs(heavy[:, 1] - light[:, 1]).mean()
    with pytest.raises(ValueError, match='payload'):
        model.predict(query)
    with pytest.raises(ValueError, match='payload'):
        model.predict(query, np.ones(3))


def test_constant_input_is_dropped() -> None:
    joints = random_joints(40, seed=8)
    joints[:, 1] = 0.6   # the paper's simulation keeps the No.2 arm at 600 mm
    for kind in KINDS:
        model = make_predictor(kind).fit(joints, sag(joints))
        assert model.metadata['normalisation']['active_inputs'] == [True, False, True, True]
        assert np.all(np.isfinite(model.predict(random_joints(5, seed=9))))


def test_rbf_default_smooths_a_pose_measured_twice() -> None:
    joints = random_joints(40, seed=11)
    rng = np.random.default_rng(12)
    twice = np.vstack([joints, joints + rng.uniform(-1e-4, 1e-4, joints.shape)])
    noisy = np.vstack([sag(joints)] * 2) + rng.normal(0.0, 2e-5, (80, 3))   # camera noise
    query = random_joints(300, seed=13)
    errors = np.abs(make_predictor('rbf').fit(twice, noisy).predict(query) - sag(query))
    once = make_predictor('rbf').fit(joints, sag(joints)).predict(query)
    assert errors.mean(axis=0)[1] < 1.2 * np.abs(once - sag(query)).mean(axis=0)[1]


def test_unknown_kind_lists_the_kinds() -> None:
    with pytest.raises(ValueError, match='mlp, rbf, gp'):
        make_predictor('svm')


@pytest.mark.parametrize('kind, settings, match', [
    ('mlp', {'hidden': [0]}, 'hidden'),
    ('mlp', {'hidden': 10}, 'must be a list'),
    ('mlp', {'activation': 'step'}, 'activation'),
    ('mlp', {'members': 1.5}, 'members'),
    ('mlp', {'members': 1}, 'members'),
    ('mlp', {'payload_input': 1}, 'payload_input'),
    ('mlp', {'learning_rate': 0.1}, 'unknown mlp settings'),
    ('rbf', {'kernel': 'bessel'}, 'kernel'),
    ('rbf', {'kernel': 'quintic', 'degree': 1}, 'degree'),
    ('rbf', {'smoothing': -1}, 'smoothing'),
    ('gp', {'noise_bounds': [1e-2, 1e-3]}, 'noise_bounds'),
    ('gp', {'noise_level': 1.0}, 'noise_level'),
])
def test_bad_settings(kind: str, settings: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make_predictor(kind, settings)


def test_settings_accept_json_numbers() -> None:
    model = make_predictor('mlp', {'weight_decay': 0, 'hidden': (5, 5)})
    assert model.settings['weight_decay'] == 0.0 and model.settings['hidden'] == [5, 5]


@pytest.mark.parametrize('kind', KINDS)
def test_bad_data(kind: str) -> None:
    joints = random_joints(20, seed=10)
    deflections = sag(joints)
    model = make_predictor(kind)
    with pytest.raises(RuntimeError, match='not fitted'):
        model.predict(joints)
    with pytest.raises(ValueError, match='joints must have shape'):
        model.fit(joints[:, :3], deflections)
    with pytest.raises(ValueError, match='deflections must have shape'):
        model.fit(joints, deflections[:-1])
    deflections[4, 1] = np.nan
    with pytest.raises(ValueError, match='NaN'):
        model.fit(joints, deflections)
    assert not model.fitted


@pytest.mark.parametrize('kind', KINDS)
def test_data_distance_grows_outside_the_learned_data(fitted: dict[str, Predictor],
                                                      kind: str, tmp_path: Path) -> None:
    model = fitted[kind]
    inside = model.data_distance(random_joints(200, seed=20))
    assert inside.shape == (200,) and inside.max() < 3.0
    training = random_joints(60, seed=1)
    assert model.data_distance(training[5]) == pytest.approx(0.0, abs=1e-9)
    outside = UPPER + 0.5 * (UPPER - LOWER)           # half the box beyond every upper limit
    assert model.data_distance(outside) > 3 * inside.max()
    model.save(tmp_path / 'm.npz')
    assert load_model(tmp_path / 'm.npz').data_distance(outside) == pytest.approx(
        model.data_distance(outside))


def test_a_change_of_an_input_constant_in_training_is_far_from_the_data() -> None:
    joints = random_joints(40, seed=8)
    joints[:, 1] = 0.6
    model = make_predictor('rbf').fit(joints, sag(joints))
    moved = joints[3] + np.array([0.0, 0.01, 0.0, 0.0])       # 10 mm longer No.2 arm
    assert model.data_distance(joints[3]) == pytest.approx(0.0, abs=1e-9)
    assert model.data_distance(moved) > 5.0


def test_only_the_gp_knows_its_position_std(fitted: dict[str, Predictor]) -> None:
    inside, far = random_joints(50, seed=21), UPPER + (UPPER - LOWER)
    gp = fitted['gp']
    assert gp.position_std(inside).max() < 0.3 * gp.position_std(far)
    std = gp.deflection_std(far)
    assert gp.position_std(far) == pytest.approx(np.hypot(std[0], std[1]))
    for kind in ('mlp', 'rbf'):
        assert fitted[kind].position_std(far) == 0.0
        assert not fitted[kind].position_std(inside).any()


def test_the_model_sees_link_angles() -> None:
    joints = np.array([[0.1, 0.6, -0.3, 0.5]])
    np.testing.assert_allclose(base.model_inputs(joints), [[0.1, 0.6, -0.2, 0.3]])


def test_a_model_of_an_older_format_is_refused(fitted: dict[str, Predictor],
                                              tmp_path: Path) -> None:
    import json

    path = tmp_path / 'old.npz'
    fitted['rbf'].save(path)
    with np.load(path) as archive:
        arrays = dict(archive)
    metadata = json.loads(str(arrays.pop('metadata')))
    metadata['format'] = 1
    np.savez(path, metadata=np.array(json.dumps(metadata)), **arrays)
    with pytest.raises(ValueError, match='model format 1.*train a new one'):
        load_model(path)


@pytest.mark.parametrize('block', [base.NEAREST_BLOCK, 1000])
def test_nearest_distance_is_what_a_kd_tree_finds(block, monkeypatch):
    """Brute force in blocks (one block, and one row of 300 pairs a block) against scipy's
    KD tree, which training uses."""
    from scipy.spatial import cKDTree

    monkeypatch.setattr(base, 'NEAREST_BLOCK', block)
    rng = np.random.default_rng(3)
    support, points = rng.normal(size=(300, 4)), rng.normal(size=(7, 4))
    np.testing.assert_allclose(base.nearest_distance(support, points),
                               cKDTree(support).query(points)[0], rtol=1e-12)
    assert base.nearest_distance(support, points[:0]).shape == (0,)
