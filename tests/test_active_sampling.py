"""Active learning poses: the most uncertain reachable candidate of the grown region, each
chosen from the samples before it; deterministic for a seed."""
from concurrent.futures import Future

import numpy as np
import pytest

from flexarm_core.kinematics import ArmGeometry, forward
from flexarm_core.params import load_config
from flexarm_core.regions import regions_from_dict
from flexarm_deflection.active_sampling import ActivePoses, ActiveSettings, choose
from flexarm_deflection.predictors import make_predictor
from flexarm_deflection.sampling import sample_poses
from flexarm_sim.plant import Plant

START = np.array([0.0, 0.6, -0.5, -0.5])
SETTINGS = ActiveSettings(initial=4, pool=48)


@pytest.fixture(scope='module')
def world():
    config = load_config('arm.yaml', 'sim.yaml')
    geometry = ArmGeometry.from_dict(config['arm'])
    learner = load_config('learner.yaml', node_name='flexarm_learner')
    region = regions_from_dict(learner['regions'])['A'].grown(
        np.asarray(learner['coverage_margin']))
    return geometry, Plant.from_dict(config['plant'], geometry), region


def campaign(world, count, seed=0, settings=SETTINGS):
    """The poses ActivePoses hands out, each measured (the plant's deflection) before the
    next is asked for; and how many samples it saw at each choice."""
    geometry, plant, region = world
    joints, seen = [], []

    def samples():
        seen.append(len(joints))
        return np.array(joints).reshape(-1, 4), plant.deflection(np.array(joints).reshape(-1, 4))

    for q in ActivePoses(geometry, region, count, seed, samples, START, settings=settings):
        joints.append(q)
    return np.array(joints), seen


def test_picks_the_most_uncertain_free_candidate(world):
    geometry, plant, region = world
    _, candidates = sample_poses(geometry, region, 40, 'sobol', seed=1)
    measured = candidates[:6]
    free = np.ones(len(candidates), dtype=bool)
    free[:6] = False
    free[20] = False
    pending = np.zeros((0, 4))
    chosen = choose(candidates, free, measured, plant.deflection(measured), pending,
                    START, geometry.velocity, ActiveSettings(near_best=1.0), seed=0)
    gp = make_predictor('gp', dict(SETTINGS.model, seed=0)).fit(measured,
                                                                plant.deflection(measured))
    std = gp.position_std(candidates)
    std[~free] = -1.0
    assert chosen == int(np.argmax(std))
    assert free[chosen]


def test_near_best_takes_the_nearest_of_the_uncertain(world):
    geometry, plant, region = world
    _, candidates = sample_poses(geometry, region, 40, 'sobol', seed=1)
    measured = candidates[:6]
    free = np.arange(len(candidates)) >= 6
    args = (candidates, free, measured, plant.deflection(measured), np.zeros((0, 4)),
            candidates[5], geometry.velocity)
    most = choose(*args, ActiveSettings(near_best=1.0), seed=0)
    near = choose(*args, ActiveSettings(near_best=0.01), seed=0)
    travel = np.max(np.abs(candidates - candidates[5]) / geometry.velocity, axis=1)
    assert near == int(np.flatnonzero(free)[np.argmin(travel[free])])
    assert travel[near] <= travel[most]


def test_reachable_distinct_poses_of_the_grown_region(world):
    geometry, _, region = world
    joints, seen = campaign(world, 9)
    assert joints.shape == (9, 4)
    assert len({tuple(q) for q in joints}) == 9
    assert np.all((joints >= geometry.lower) & (joints <= geometry.upper))
    tip = forward(geometry, joints)
    assert np.all((tip >= region.lower - 1e-9) & (tip <= region.upper + 1e-9))
    _, pool = sample_poses(geometry, region, SETTINGS.pool, 'sobol', seed=0)
    assert all(np.any(np.all(pool == q, axis=1)) for q in joints)
    # the first poses are space-filling (the sequence's first), then each is chosen from
    # the samples before it: all but the one under way
    assert {tuple(q) for q in joints[:4]} == {tuple(q) for q in pool[:4]}
    assert seen == list(range(3, 8))


def test_deterministic_for_a_seed(world):
    first, _ = campaign(world, 7, seed=2)
    again, _ = campaign(world, 7, seed=2)
    other, _ = campaign(world, 7, seed=3)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)


def test_fewer_poses_than_the_space_filling_start(world):
    joints, seen = campaign(world, 2)
    assert len(joints) == 2 and seen == []


def test_settings_checked():
    with pytest.raises(ValueError):
        ActiveSettings(initial=1)
    with pytest.raises(ValueError):
        ActiveSettings(near_best=0.0)


def test_a_choice_not_ready_is_not_waited_for(world):
    """A worker that never answers: the space-filling candidates, in order, and no wait."""
    geometry, plant, region = world
    joints = []
    poses = ActivePoses(geometry, region, 7, 0, lambda: (np.array(joints).reshape(-1, 4),
                                                          plant.deflection(np.array(joints))),
                        START, lambda *_: Future(), SETTINGS)
    for q in poses:
        joints.append(q)
    _, pool = sample_poses(geometry, region, SETTINGS.pool, 'sobol', seed=0)
    np.testing.assert_array_equal(np.sort(np.array(joints), axis=0), np.sort(pool[:7], axis=0))
