"""``auto``: it picks the kind whose structure made the data, through the predictor and through
the learner's training, and saves the choice with its scores."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_deflection import selection
from flexarm_deflection.models import load_model, make_model
from flexarm_deflection.predictors import greybox, kinematic
from flexarm_deflection.selection import AutoPredictor
from flexarm_description.chain import TIP_FRAME
from flexarm_description.urdf_model import robot_description
from flexarm_learning.elastostatic import TERMS, ElastostaticModel
from flexarm_learning.urdf_arm import UrdfArm

SAMPLES = 24
LOWER = np.array([-0.6, 0.3, -1.6, -1.0])
UPPER = np.array([0.3, 0.8, 0.0, 1.0])
ERRORS = np.array([1.7e-4, 5e-4, -2.6e-4, 3.5e-4, 3e-4, -4e-4, 2e-4])   # kinematic.PARAMETERS
GEOMETRY = {'link3': 0.4, 'link4': 0.4, 'offset': 0.015}


def random_joints(n: int, seed: int) -> np.ndarray:
    return LOWER + (UPPER - LOWER) * np.random.default_rng(seed).random((n, 4))


def joints() -> np.ndarray:
    return random_joints(SAMPLES, seed=11)


def miscalibrated(q: np.ndarray) -> np.ndarray:
    """The deflection of a rigid arm with joint zero and link errors."""
    return (kinematic.perturbed_pose(GEOMETRY, q, ERRORS)
            - kinematic.perturbed_pose(GEOMETRY, q, np.zeros(kinematic.KINEMATIC)))


def sagging(q: np.ndarray, payload: float = 0.0) -> np.ndarray:
    """... and with compliant joints 3 and 4 and a bending fourth arm (the learning core's
    structure on the description's URDF, the moments' units N·m)."""
    description = greybox.description()
    arm = UrdfArm.from_xml(robot_description(ArmGeometry.from_dict(description),
                                             description['inertia'], hardware=''), TIP_FRAME)
    truth = ElastostaticModel(arm, registration=False, terms=TERMS)
    truth.compliances[2:, 1] = [4e-5, 2.4e-4]
    truth.bending[3, 1], truth.shift[3, 2] = 8e-4, 3.4e-4
    rigid = arm.chain_at(q, np.zeros(3))
    bent = greybox.planar(*truth.predict_pose(q, payload)) - greybox.planar(rigid.target,
                                                                    rigid.tip_rotation)
    return bent + miscalibrated(q)


def noisy(deflections: np.ndarray) -> np.ndarray:
    """With a camera's noise (5 µm, 5 µrad)."""
    return deflections + np.random.default_rng(12).normal(0.0, 5e-6, deflections.shape)


def smooth(q: np.ndarray) -> np.ndarray:
    """A deflection neither the kinematic errors nor the gravity moments explain."""
    return 1e-3 * np.column_stack([np.sin(2 * q[:, 0]) * q[:, 1], np.cos(q[:, 2] + q[:, 3]),
                                   np.sin(q[:, 3])])


@pytest.fixture(scope='module')
def gravity() -> AutoPredictor:
    q = joints()
    return make_model('auto', {'kinds': ['kinematic', 'greybox']}).fit(q, noisy(sagging(q)))


@pytest.mark.parametrize('truth, kinds, kind', [
    (miscalibrated, ['kinematic', 'greybox'], 'kinematic'),   # the simpler one, if it is enough
    (smooth, ['kinematic', 'greybox', 'gp'], 'gp')])
def test_picks_the_kind_that_made_the_data(truth, kinds: list[str], kind: str) -> None:  # noqa: ANN001
    q = joints()
    model = make_model('auto', {'kinds': kinds}).fit(q, noisy(truth(q)))
    assert model.chosen.kind == kind
    scores = model.metadata['auto']['scores']
    assert set(scores) == set(kinds)
    assert min(scores, key=scores.get) == kind


def test_picks_the_greybox_for_a_sagging_arm(gravity: AutoPredictor) -> None:
    assert gravity.chosen.kind == 'greybox' and gravity.metadata['auto']['chosen'] == 'greybox'
    query = random_joints(100, seed=13)
    np.testing.assert_array_equal(gravity.predict(query), gravity.chosen.predict(query))
    assert np.abs(gravity.predict(query) - sagging(query)).max() < 5e-5   # measured 3.4e-5
    assert gravity.payload_physical       # the chosen grey-box carries the payload
    np.testing.assert_array_equal(gravity.predict(query, 5.0), gravity.chosen.predict(query, 5.0))
    assert np.abs(gravity.predict(query, 5.0) - sagging(query, 5.0)).max() < 1e-4   # 22 mm more


def test_save_load_round_trip(gravity: AutoPredictor, tmp_path: Path) -> None:
    path = tmp_path / 'auto.npz'
    gravity.save(path)
    loaded = load_model(path)
    assert type(loaded) is AutoPredictor and loaded.kind == 'auto'
    assert loaded.metadata == gravity.metadata and loaded.chosen.kind == 'greybox'
    query = random_joints(50, seed=14)
    np.testing.assert_allclose(loaded.predict(query), gravity.predict(query), rtol=0,
                               atol=1e-12)
    np.testing.assert_allclose(loaded.position_std(query), gravity.position_std(query),
                               rtol=1e-9, atol=1e-15)
    assert loaded.data_distance(query[0]) == pytest.approx(gravity.data_distance(query[0]))


def test_the_learner_training_chooses_the_kind_once() -> None:
    q = joints()
    model, metrics = selection.fit_robust('auto', {'kinds': ['kinematic', 'greybox']}, q,
                                         noisy(sagging(q)))
    assert isinstance(model, AutoPredictor) and model.chosen.kind == 'greybox'
    assert metrics.selected_settings.startswith('{"kind": "greybox"')
    assert set(model.metadata['auto']['scores']) == {'kinematic', 'greybox'}
    assert metrics.max_error_y < 1e-4


@pytest.mark.parametrize('settings', [{'kinds': []}, {'kinds': ['auto']}, {'kinds': ['svm']},
                                      {'folds': 3}])
def test_bad_settings(settings: dict) -> None:
    with pytest.raises(ValueError):
        make_model('auto', settings)


def test_auto_is_the_learner_default() -> None:
    assert load_config('learner.yaml', node_name='flexarm_learner')['default_kind'] == 'auto'
