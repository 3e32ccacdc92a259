"""The compensation algorithm on a known deflection (the simulator's plant as the predictor)."""
import math

import numpy as np
import pytest

from flexarm_control.compensator import CompensationError, Compensator
from flexarm_control.kinematics import ArmGeometry, UnreachableError, forward, limit_violation
from flexarm_control.params import load_config
from flexarm_sim.plant import Plant

TARGETS = [(1.45, -0.15, -45), (1.55, 0.0, -22), (1.0, -0.5, -100), (1.3, -0.2, -61),
           (1.1, 0.2, 10), (0.9, -0.6, -120)]


@pytest.fixture(scope='module')
def setup():
    config = load_config('arm.yaml', 'sim.yaml', 'compensator.yaml',
                         node_name='flexarm_compensator')
    geometry = ArmGeometry.from_dict(config['arm'])
    return geometry, Plant.from_dict(config['plant'], geometry), Compensator(
        geometry, config['compensation'])


def pose(t) -> np.ndarray:
    return np.array([t[0], t[1], math.radians(t[2])])


@pytest.mark.parametrize('t', TARGETS)
def test_perfect_predictor_puts_the_tip_on_target(setup, t):
    geometry, plant, compensator = setup
    target = pose(t)
    rigid_error = plant.pose(compensator.rigid(target).joints) - target
    plan = compensator.predictive(target, plant.deflection)
    error = plant.pose(plan.joints) - target
    assert np.hypot(*rigid_error[:2]) > 3e-3
    assert np.hypot(*error[:2]) < 1e-6 and abs(error[2]) < 1e-6
    assert 2 <= plan.iterations < 20 and plan.step < 1e-7
    assert limit_violation(geometry, plan.joints) is None
    np.testing.assert_allclose(forward(geometry, plan.joints), plan.commanded_pose, atol=1e-9)


def test_rigid_plan_is_plain_inverse_kinematics(setup):
    geometry, _, compensator = setup
    plan = compensator.rigid(pose(TARGETS[0]))
    np.testing.assert_allclose(forward(geometry, plan.joints), pose(TARGETS[0]), atol=1e-12)
    assert plan.iterations == 0 and not plan.predicted_deflection.any()


def test_closed_loop_correction_removes_a_model_error(setup):
    _, plant, compensator = setup
    target = pose(TARGETS[3])
    biased = lambda q: plant.deflection(q) * 0.8            # a predictor 20 % short
    plan = compensator.predictive(target, biased)
    errors = []
    for _ in range(6):
        measured = plant.pose(plan.joints)
        errors.append(np.hypot(*(measured - target)[:2]))
        plan = compensator.correct(plan, target, measured)
    assert errors[0] > 1e-3 and errors[-1] < 1e-6
    assert all(b < a for a, b in zip(errors, errors[1:]))


def test_unreachable_targets_are_refused(setup):
    _, plant, compensator = setup
    with pytest.raises(UnreachableError):
        compensator.rigid(np.array([2.0, 0.0, 0.0]))
    # Reachable rigidly, but not once the tip must be raised by the compensation.
    edge = forward(compensator.geometry, np.array([0.0, 0.8, -0.09, 0.09]))
    with pytest.raises(CompensationError, match='unreachable'):
        compensator.predictive(edge, lambda q: np.array([-0.05, -0.05, 0.0]))


def theta1_slope(slope: float):
    """A synthetic predictor: dy changes ``slope`` × 1.3 m per radian of theta1."""
    return lambda q: np.array([0.0, slope * 1.3 * (q[0] - 0.16), 0.0])


def test_divergent_iteration_is_reported(setup):
    _, _, compensator = setup
    # Deflection changing faster than the motion: violates section 3-2, the steps grow.
    with pytest.raises(CompensationError, match='compensation diverges'):
        compensator.predictive(pose(TARGETS[3]), theta1_slope(-2.0))


def test_iteration_that_does_not_converge_is_refused(setup):
    geometry, _, compensator = setup
    slow = theta1_slope(-1.2)   # contracts, but oscillating slowly
    few = Compensator(geometry, {'max_iterations': 5, 'tolerance': 1e-7, 'gain': 1.0})
    with pytest.raises(CompensationError, match='does not converge: .* after 5 iterations'):
        few.predictive(pose(TARGETS[3]), slow)
    plan = Compensator(geometry, {'max_iterations': 200, 'tolerance': 1e-7, 'gain': 1.0}
                       ).predictive(pose(TARGETS[3]), slow)
    assert plan.step < 1e-7 and plan.iterations < 200


def test_settings_are_validated(setup):
    geometry = setup[0]
    for iterations in (0, 1):   # convergence is judged from the second iteration
        with pytest.raises(ValueError):
            Compensator(geometry, {'max_iterations': iterations, 'tolerance': 1e-7,
                                   'gain': 1.0})
