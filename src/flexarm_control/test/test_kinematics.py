"""Rigid kinematics: FK/IK round trips, the redundancy rule, limits and unreachable targets."""
import math

import numpy as np
import pytest

from flexarm_control.kinematics import (ArmGeometry, UnreachableError, forward, inverse,
                                        limit_violation, pose_error, wrap_angle)
from flexarm_control.params import load_config


@pytest.fixture(scope='module')
def geometry() -> ArmGeometry:
    return ArmGeometry.from_dict(load_config('arm.yaml')['arm'])


def test_forward_matches_the_paper_equations(geometry):
    q = np.array([0.3, 0.55, -0.7, 0.4])
    t1, t2, t3, t4 = q
    x = 0.4 * math.cos(t1 + t3 + t4) + 0.4 * math.cos(t1 + t3) + t2 * math.cos(t1) \
        - 0.015 * math.sin(t1)
    y = 0.4 * math.sin(t1 + t3 + t4) + 0.4 * math.sin(t1 + t3) + t2 * math.sin(t1) \
        + 0.015 * math.cos(t1)
    np.testing.assert_allclose(forward(geometry, q), [x, y, t1 + t3 + t4], atol=1e-12)


def test_forward_is_vectorised(geometry):
    q = np.random.default_rng(1).uniform(geometry.lower, geometry.upper, (7, 5, 4))
    poses = forward(geometry, q)
    assert poses.shape == (7, 5, 3)
    np.testing.assert_allclose(poses[3, 2], forward(geometry, q[3, 2]))


def test_inverse_round_trips_inside_the_limits(geometry):
    rng = np.random.default_rng(2)
    q = rng.uniform(geometry.lower, geometry.upper, (300, 4))
    q[:, 2] = rng.uniform(-2.5, -0.2, 300)       # elbow bent enough to be away from singular
    solved = 0
    for pose in forward(geometry, q):
        try:
            joints = inverse(geometry, pose)
        except UnreachableError:
            continue
        solved += 1
        assert limit_violation(geometry, joints) is None
        position, angle = pose_error(pose, forward(geometry, joints))
        assert position < 1e-9 and angle < 1e-9
    assert solved > 250


def test_preferred_extension_is_used_when_reachable(geometry):
    pose = forward(geometry, np.array([-0.2, geometry.preferred_extension, -0.6, -0.3]))
    assert inverse(geometry, pose)[1] == pytest.approx(geometry.preferred_extension)


def test_far_target_takes_the_nearest_reachable_extension(geometry):
    # Table 10 target 2 (1550, 0, -22 deg) is out of reach with 0.6 m.
    pose = np.array([1.55, 0.0, math.radians(-22)])
    joints = inverse(geometry, pose)
    assert joints[1] > geometry.preferred_extension
    with pytest.raises(UnreachableError):
        inverse(geometry, pose, extension=joints[1] - 2 * geometry.extension_step)
    np.testing.assert_allclose(forward(geometry, joints), pose, atol=1e-12)


@pytest.mark.parametrize('pose', [
    [2.5, 0.0, 0.0],                       # beyond the longest arm
    [1.0, 0.0, math.pi],                   # tip pointing back: wrist 1.4 m out
    [float('nan'), 0.0, 0.0],
    [1.0, float('inf'), 0.0],
])
def test_unreachable_or_invalid_targets_raise_with_a_reason(geometry, pose):
    with pytest.raises(UnreachableError, match='.+'):
        inverse(geometry, np.array(pose))


def test_limit_violation_names_the_joint(geometry):
    q = np.array([0.0, 0.9, 0.0, 0.0])
    assert 'joint2' in limit_violation(geometry, q)
    assert limit_violation(geometry, np.array([0.0, 0.5, 0.0, 0.0])) is None


def test_wrap_angle():
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    np.testing.assert_allclose(wrap_angle(np.array([0.1, -7.0])), [0.1, -7.0 + 2 * math.pi])
    assert wrap_angle(math.pi) == wrap_angle(-math.pi) == math.pi      # (-π, π]


def test_geometry_rejects_bad_config():
    d = load_config('arm.yaml')['arm']
    with pytest.raises(ValueError):
        ArmGeometry.from_dict({**d, 'lower': d['upper']})
    with pytest.raises(ValueError):
        ArmGeometry.from_dict({**d, 'preferred_extension': 2.0})


def test_extension_rule_matches_an_exhaustive_search(geometry):
    """The reach-interval pruning picks what trying every grid value in order would pick."""
    from flexarm_control.kinematics import _solve_fixed

    lo, hi, step = geometry.lower[1], geometry.upper[1], geometry.extension_step
    grid = np.linspace(lo, hi, int(round((hi - lo) / step)) + 1)
    grid = [geometry.preferred_extension,
            *grid[np.argsort(np.abs(grid - geometry.preferred_extension), kind='stable')]]
    rng = np.random.default_rng(5)
    for pose in rng.uniform([0.2, -1.0, -math.pi], [1.7, 0.8, math.pi], (150, 3)):
        expected = next((q for q in (_solve_fixed(geometry, pose, e) for e in grid)
                         if q is not None), None)
        if expected is None:
            with pytest.raises(UnreachableError):
                inverse(geometry, pose)
        else:
            np.testing.assert_allclose(inverse(geometry, pose), expected, atol=1e-12)
