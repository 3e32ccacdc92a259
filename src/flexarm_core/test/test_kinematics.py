"""Rigid kinematics: FK/IK round trips, the redundancy rule, limits and unreachable targets."""
import math

import numpy as np
import pytest

from flexarm_core.kinematics import (
    ArmGeometry,
    UnreachableError,
    elbow_bend,
    forward,
    inverse,
    limit_violation,
    pose_error,
    reach_margins,
    wrap_angle,
)
from flexarm_core.params import load_config


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


def test_far_target_takes_an_extension_with_reach_to_spare(geometry):
    # Out of reach with 0.6 m: the elbow is nearly stretched at 0.7 m.
    pose = forward(geometry, np.array([-0.1, 0.7, -0.1, -0.2]))
    joints = inverse(geometry, pose)
    assert joints[1] > geometry.preferred_extension
    np.testing.assert_allclose(forward(geometry, joints), pose, atol=1e-12)
    assert reach_margins(geometry, pose, np.array([joints[1]]))[0] >= geometry.reach_margin
    # The next extension towards the preferred one would leave less than the margin.
    closer = joints[1] - geometry.extension_step
    assert reach_margins(geometry, pose, np.array([closer]))[0] < geometry.reach_margin
    assert elbow_bend(geometry, joints) > math.radians(20)


def test_reach_margin_is_the_distance_the_wrist_can_move_out(geometry):
    """Moving the target radially outward by just under the margin stays reachable with the
    same extension; by just over it, it does not."""
    from flexarm_core.kinematics import solve_fixed

    rng = np.random.default_rng(7)
    checked = 0
    for pose in rng.uniform([0.9, -0.6, -1.8], [1.6, 0.2, 0.0], (200, 3)):
        extension = 0.7
        margin = reach_margins(geometry, pose, np.array([extension]))[0]
        if not 0.005 < margin < 0.2 or solve_fixed(geometry, pose, extension) is None:
            continue
        wrist = pose[:2] - geometry.link4 * np.array([math.cos(pose[2]), math.sin(pose[2])])
        wrist_from_joint1 = wrist / np.linalg.norm(wrist)
        for factor, reachable in ((0.99, True), (1.01, False)):
            moved = pose + np.append(wrist_from_joint1 * margin * factor, 0.0)
            r_margin = reach_margins(geometry, moved, np.array([extension]))[0]
            assert (r_margin >= 0) == reachable
        checked += 1
    assert checked > 20


@pytest.mark.parametrize('pose', [
    [1.55, 0.0, math.radians(-22)],                            # Table 10 target A2
    [1.5942, 0.0988, 0.03]])        # forward(0.1, 0.8 m, -0.12, 0.05): elbow bent 7 deg
def test_target_at_the_edge_of_reach_takes_the_largest_margin(geometry, pose):
    # No extension leaves the full margin: the one with the largest is taken.
    pose = np.array(pose)
    joints = inverse(geometry, pose)
    grid = np.arange(geometry.lower[1], geometry.upper[1] + 1e-9, geometry.extension_step)
    margins = reach_margins(geometry, pose, grid)
    assert margins.max() < geometry.reach_margin
    assert reach_margins(geometry, pose, np.array([joints[1]]))[0] == pytest.approx(
        margins.max(), abs=1e-9)


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
    with pytest.raises(ValueError):
        ArmGeometry.from_dict({**d, 'reach_margin': -0.01})


def test_extension_rule_matches_an_exhaustive_search(geometry):
    """The rule picks what trying every grid value in the rule's order would pick."""
    from flexarm_core.kinematics import solve_fixed

    lo, hi, step = geometry.lower[1], geometry.upper[1], geometry.extension_step
    grid = np.round(np.linspace(lo, hi, int(round((hi - lo) / step)) + 1), 9)
    rng = np.random.default_rng(5)
    for pose in rng.uniform([0.2, -1.0, -math.pi], [1.7, 0.8, math.pi], (150, 3)):
        margins = reach_margins(geometry, pose, grid)
        full = [e for _, e in sorted((abs(e - geometry.preferred_extension), e)
                                     for e, m in zip(grid, margins)
                                     if m >= geometry.reach_margin)]
        some = [e for _, e in sorted((-m, e) for e, m in zip(grid, margins)
                                     if 0 <= m < geometry.reach_margin)]
        expected = next((q for q in (solve_fixed(geometry, pose, e) for e in full + some)
                         if q is not None), None)
        if expected is None:
            with pytest.raises(UnreachableError):
                inverse(geometry, pose)
        else:
            np.testing.assert_allclose(inverse(geometry, pose), expected, atol=1e-12)
