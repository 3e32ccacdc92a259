"""A payload declared beyond the trained ones: how the bounds grew, and what brings them
back."""
import numpy as np
import pytest

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_core.regions import regions_from_dict
from flexarm_deflection.payload_bounds import bound_report, needs_retraining
from flexarm_deflection.sampling import sample_poses
from flexarm_deflection.selection import fit_robust
from flexarm_sim.plant import Plant

CONFIG = load_config('arm.yaml', 'sim.yaml', 'learner.yaml', node_name='flexarm_learner')


@pytest.fixture(scope='module')
def trained_at_0():
    geometry = ArmGeometry.from_dict(CONFIG['arm'])
    regions = regions_from_dict(CONFIG['regions'])
    plant = Plant.from_dict(CONFIG['plant'], geometry)
    joints = sample_poses(geometry, regions['A'], 20, 'sobol', 0)[1]
    noise = np.random.default_rng(0).normal(0.0, 5e-6, (20, 3))
    model, _ = fit_robust('greybox', {'residual': 'none'}, joints,
                          plant.deflection(joints) + noise, np.zeros(20), folds=5)
    return model, {'A': regions['A']}, geometry


def test_the_bounds_grow_with_the_payload_and_a_refresh_is_named(trained_at_0):
    model, regions, geometry = trained_at_0
    report = bound_report(model, regions, geometry, [0.0], 5.0)
    before, after = (float(v) for v in report.split('region A ')[1].split(' mm')[0].split(' -> '))
    assert after > 10 * before and 'flexarm refresh' in report and 'trained at 0 kg' in report
    assert bound_report(model, regions, geometry, [0.0], 0.005) == ''


def test_a_model_that_cannot_carry_the_payload_says_predictive_is_refused(trained_at_0):
    _, regions, geometry = trained_at_0
    joints = sample_poses(geometry, regions['A'], 12, 'sobol', 0)[1]
    gp, _ = fit_robust('gp', None, joints, np.zeros((12, 3)) + 1e-3 * joints[:, :3], folds=3)
    assert 'PREDICTIVE goals are refused' in bound_report(gp, regions, geometry, [0.0], 2.0)


def test_only_a_payload_none_of_the_trained_ones_needs_retraining():
    assert needs_retraining([0.0], 5.0) and not needs_retraining([0.0, 5.0], 5.004)
    assert not needs_retraining([], 5.0)
