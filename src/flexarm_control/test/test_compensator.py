"""The compensation algorithm on a known deflection (the simulator's plant as the predictor)
and on synthetic predictors that break the paper's iteration."""
import math

import numpy as np
import pytest

from flexarm_control.execution.compensator import CompensationError, Compensator
from flexarm_core.kinematics import (
    ArmGeometry,
    UnreachableError,
    forward,
    inverse,
    limit_violation,
)
from flexarm_core.params import load_config
from flexarm_deflection.deflection_slope import deflection_slope
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


def with_settings(geometry: ArmGeometry, **changes) -> Compensator:
    settings = {'method': 'newton', 'max_iterations': 20, 'tolerance': 1e-6,
                'angle_tolerance': 1e-6, 'gain': 1.0}
    return Compensator(geometry, {**settings, **changes})


@pytest.mark.parametrize('method', ['newton', 'paper'])
@pytest.mark.parametrize('t', TARGETS)
def test_perfect_predictor_puts_the_tip_on_target(setup, t, method):
    geometry, plant, _ = setup
    compensator = with_settings(geometry, method=method)
    target = pose(t)
    rigid_error = plant.pose(compensator.rigid(target).joints) - target
    plan = compensator.predictive(target, plant.deflection)
    error = plant.pose(plan.joints) - target
    assert np.hypot(*rigid_error[:2]) > 3e-3
    assert np.hypot(*error[:2]) < 2e-6 and abs(error[2]) < 2e-6
    assert 1 <= plan.iterations <= (4 if method == 'newton' else 19)
    assert limit_violation(geometry, plan.joints) is None
    np.testing.assert_allclose(forward(geometry, plan.joints), plan.commanded_pose, atol=1e-9)


def test_newton_keeps_the_extension_of_the_first_compensated_pose(setup):
    geometry, plant, compensator = setup
    target = pose(TARGETS[1])
    first = target - plant.deflection(inverse(geometry, target))
    plan = compensator.predictive(target, plant.deflection)
    assert plan.joints[1] == inverse(geometry, first)[1]


def test_rigid_plan_is_plain_inverse_kinematics(setup):
    geometry, _, compensator = setup
    plan = compensator.rigid(pose(TARGETS[0]))
    np.testing.assert_allclose(forward(geometry, plan.joints), pose(TARGETS[0]), atol=1e-12)
    assert plan.iterations == 0 and not plan.predicted_deflection.any()


def test_closed_loop_correction_removes_a_model_error(setup):
    _, plant, compensator = setup
    target = pose(TARGETS[3])
    def biased(q: np.ndarray) -> np.ndarray:               # a predictor 20 % short
        return plant.deflection(q) * 0.8

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
        compensator.predictive(edge, lambda q: np.array([-0.05, -0.05, 0.0]) + 0 * q[..., :3])


def theta1_slope(slope: float, centre: float):
    """A synthetic predictor: a 10 mm sag at theta1 = ``centre`` that changes ``slope`` ×
    1.3 m per radian of theta1 (about ``slope`` × the tip's own y motion)."""
    def predict(q: np.ndarray) -> np.ndarray:
        q = np.asarray(q)
        dy = slope * 1.3 * (q[..., 0] - centre) - 0.01
        return np.stack([0 * dy, dy, 0 * dy], axis=-1)
    return predict


@pytest.mark.parametrize('slope', [-1.5, -3.0, 1.5])
def test_newton_solves_where_the_paper_iteration_fails(setup, slope):
    geometry, _, _ = setup
    target = pose(TARGETS[3])
    predict = theta1_slope(slope, inverse(geometry, target)[0])
    with pytest.raises(CompensationError, match='diverges|does not converge'):
        with_settings(geometry, method='paper').predictive(target, predict)
    plan = with_settings(geometry).predictive(target, predict)
    predicted_tip = forward(geometry, plan.joints) + predict(plan.joints)
    assert np.hypot(*(predicted_tip - target)[:2]) < 1e-6 and plan.iterations < 10


def test_deflection_that_cancels_the_motion_has_no_solution(setup):
    geometry, _, compensator = setup
    # The predicted tip stays at y = -0.3 m whatever the joints: y = -0.2 m cannot be reached.
    cancel = lambda q: np.stack(    # noqa: E731
        [0 * q[..., 0], -forward(geometry, q)[..., 1] - 0.3, 0 * q[..., 0]], axis=-1)
    with pytest.raises(CompensationError, match='no solution|does not converge'):
        compensator.predictive(pose(TARGETS[3]), cancel)


def test_deflection_slope(setup):
    geometry, plant, _ = setup
    q = np.array([inverse(geometry, pose(t)) for t in TARGETS])
    assert np.all(deflection_slope(geometry, plant.deflection, q) < 0.15)
    # Δy = 0.3 y_rigid: dΔ/dx* has the single entry 0.3.
    proportional = lambda q: np.stack(    # noqa: E731
        [0 * q[..., 0], 0.3 * forward(geometry, q)[..., 1], 0 * q[..., 0]], axis=-1)
    np.testing.assert_allclose(deflection_slope(geometry, proportional, q), 0.3, rtol=1e-4)


def test_settings_are_validated(setup):
    geometry = setup[0]
    for change in ({'max_iterations': 1}, {'tolerance': 0.0}, {'method': 'guess'},
                   {'angle_tolerance': -1.0}, {'gain': 2.0}):
        with pytest.raises(ValueError):
            with_settings(geometry, **change)
