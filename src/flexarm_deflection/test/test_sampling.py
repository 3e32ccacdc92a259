"""Learning poses and their visiting order: a short path through every pose once."""
import numpy as np
import pytest

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_core.regions import regions_from_dict
from flexarm_deflection.sampling import STRATEGIES, path_time, sample_poses, travel_order


def greedy(joints, start, velocity):
    """The nearest-neighbour order travel_order starts from."""
    remaining, order, here = list(range(len(joints))), [], start
    while remaining:
        times = np.max(np.abs(joints[remaining] - here) / velocity, axis=1)
        order.append(remaining.pop(int(np.argmin(times))))
        here = joints[order[-1]]
    return np.array(order)


def test_visits_every_pose_once_and_never_longer_than_greedy():
    rng = np.random.default_rng(3)
    for _ in range(60):
        n = int(rng.integers(1, 25))
        joints, start = rng.random((n, 4)), rng.random(4)
        velocity = rng.random(4) + 0.1
        order = travel_order(joints, start, velocity)
        assert sorted(order.tolist()) == list(range(n))
        assert (path_time(joints[order], start, velocity)
                <= path_time(joints[greedy(joints, start, velocity)], start, velocity) + 1e-12)


def test_shorter_than_greedy_on_learning_poses():
    config = load_config('arm.yaml')
    geometry = ArmGeometry.from_dict(config['arm'])
    region = regions_from_dict(load_config('learner.yaml', node_name='flexarm_learner')[
        'regions'])['B']
    _, joints = sample_poses(geometry, region, 30, 'sobol', seed=0)
    start = np.array([0.0, 0.6, -0.5, -0.5])
    v = geometry.velocity
    assert (path_time(joints[travel_order(joints, start, v)], start, v)
            < path_time(joints[greedy(joints, start, v)], start, v))


def test_empty_and_single_pose():
    v = np.ones(4)
    assert travel_order(np.zeros((0, 4)), np.zeros(4), v).tolist() == []
    assert travel_order(np.ones((1, 4)), np.zeros(4), v).tolist() == [0]


def test_active_is_a_strategy_but_not_a_sequence():
    assert 'active' in STRATEGIES
    geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
    region = regions_from_dict(load_config('learner.yaml', node_name='flexarm_learner')[
        'regions'])['A']
    with pytest.raises(ValueError, match='unknown strategy'):
        sample_poses(geometry, region, 4, 'active')
