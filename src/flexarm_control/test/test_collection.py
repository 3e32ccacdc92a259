"""Collection loop: a sample per pose on disk in order, retries, skips, cancel, lost arm."""
import dataclasses

import numpy as np
import pytest
from fake_arm import FakeArm

from flexarm_control.execution.collection import BLIND_POSES, Collector
from flexarm_core.kinematics import ArmGeometry, inverse
from flexarm_core.params import load_config
from flexarm_motion.arm_motion import ArmMotion, MotionSettings
from flexarm_sim.plant import Plant

START = np.array([0.0, 0.6, 0.0, 0.0])


@pytest.fixture(scope='module')
def world():
    config = load_config('arm.yaml', 'sim.yaml', 'motion.yaml', node_name='flexarm_learner')
    geometry = ArmGeometry.from_dict(config['arm'])
    poses = [inverse(geometry, np.array(p)) for p in
             ([1.45, -0.15, -0.8], [1.55, 0.0, -0.4], [1.0, -0.5, -1.7], [1.3, -0.2, -1.1])]
    return (geometry, Plant.from_dict(config['plant'], geometry),
            dataclasses.replace(MotionSettings.from_dict(config['motion']),
                                approach=np.zeros(4)), poses)     # one command per move


def collect(world, setup=None, retries=2):
    geometry, plant, settings, poses = world
    arm = FakeArm(plant, START)
    if setup:
        setup(arm)
    stored, progress, warnings = [], [], []
    collector = Collector(ArmMotion(arm, geometry, settings), geometry, retries,
                          clock=lambda: 12.5, warn=warnings.append)
    counts = collector.collect(poses, 2.0, stored.append, arm.abort,
                               lambda k, c, s: progress.append((k, c.skipped, s is not None)))
    return counts, stored, progress, warnings, arm


def test_every_pose_gives_its_measured_deflection_in_order(world):
    counts, stored, progress, warnings, _ = collect(world)
    assert (counts.collected, counts.skipped, counts.canceled, counts.stopped) == (4, 0, False, '')
    plant, poses = world[1], world[3]
    for sample, joints in zip(stored, poses):
        np.testing.assert_allclose(sample.joints, joints)
        np.testing.assert_allclose(sample.deflection, plant.deflection(joints), atol=1e-12)
        assert sample.payload == 2.0 and sample.stamp == 12.5 and sample.holes_used == 12
    assert progress == [(1, 0, True), (2, 0, True), (3, 0, True), (4, 0, True)]
    assert not warnings


def test_a_pose_that_cannot_be_measured_is_retried_then_skipped(world):
    counts, stored, progress, warnings, arm = collect(
        world, lambda arm: arm.blind_moves.update({2, 3, 4}))   # pose 2: all 3 attempts
    assert (counts.collected, counts.skipped) == (3, 1) and len(stored) == 3
    assert len(arm.commands) == 6 and len(warnings) == 3
    assert progress[1] == (2, 1, False)


def test_cancel_keeps_what_was_stored_and_holds_the_arm(world):
    counts, stored, progress, _, arm = collect(world, lambda arm: setattr(
        arm, 'cancel_at_move', 3))
    assert counts.canceled and counts.collected == 2 and len(stored) == 2
    assert arm.holds == 1 and len(progress) == 2


def test_a_lost_controller_ends_the_collection_at_once(world):
    def lose_after_first(arm):
        original = arm.move

        def move(q, *args):
            arm.silent = len(arm.commands) >= 1
            return original(q, *args)
        arm.move = move
    counts, stored, _, _, arm = collect(world, lose_after_first)
    assert counts.collected == 1 and 'stopped publishing /joint_states' in counts.stopped
    assert len(arm.commands) == 2            # no retries, no further poses


def test_negative_retries_are_refused(world):
    geometry, plant, settings, _ = world
    with pytest.raises(ValueError, match='retries'):
        Collector(ArmMotion(FakeArm(plant, START), geometry, settings), geometry, -1,
                  clock=lambda: 0.0)


def test_a_blind_camera_ends_the_collection_after_a_few_poses_with_its_reason(world):
    counts, stored, progress, warnings, arm = collect(
        world, lambda arm: arm.blind_moves.update(range(1, 100)))
    assert (counts.collected, counts.skipped) == (0, BLIND_POSES) and not stored
    assert len(arm.commands) == 3 * BLIND_POSES          # the 4th pose is not visited
    assert counts.stopped.startswith(f'no valid tip measurement at {BLIND_POSES} poses in a '
                                     'row, the camera cannot measure: the vision node found '
                                     'no valid pose in 25 frame(s): fit residual 0.155 mm')
    assert all(w.endswith('fit residual 0.155 mm RMS too large') for w in warnings), warnings
    assert len(progress) == BLIND_POSES


def test_samples_record_their_motion_and_none_is_stored_once_the_arm_was_taken(world):
    geometry, plant, settings, poses = world
    arm = FakeArm(plant, START)
    stored = []
    lost = iter(['', '', 'motion m1 no longer holds the arm: canceled by /op'])
    counts = Collector(ArmMotion(arm, geometry, settings), geometry, 2,
                       clock=lambda: 0.0).collect(poses, 0.0, stored.append, arm.abort,
                                                  motion='m1', lost=lambda: next(lost))
    assert [s.motion for s in stored] == ['m1', 'm1']
    assert counts.collected == 2 and counts.stopped == (
        'sample 3 refused: the arm was not held by this motion alone (motion m1 no longer '
        'holds the arm: canceled by /op)')
