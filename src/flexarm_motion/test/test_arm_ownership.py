"""The arm owner's policy: one motion at a time, refusals that name the running motion."""
from __future__ import annotations

import itertools

from flexarm_motion.arm_ownership import ArmOwnership, Holder, Motion, Refused

LEARNER = Holder('/flexarm_learner', 101, 'host', 5)
COMPENSATOR = Holder('/flexarm_compensator', 102, 'host', 6)


def ownership() -> ArmOwnership:
    ids = itertools.count(1)
    return ArmOwnership(lambda: f'm{next(ids)}')


def test_a_second_claim_is_refused_naming_the_running_motion() -> None:
    arm = ownership()
    first = arm.claim('collect', '6 samples in region A', 'goal sent by /cli_a', LEARNER, 1.0)
    assert isinstance(first, Motion) and first.motion_id == 'm1'
    second = arm.claim('move', 'MoveToPose "t" (RIGID)', 'goal sent by /cli_b', COMPENSATOR,
                       2.0)
    assert isinstance(second, Refused) and second.running == first
    for part in ('collect', '6 samples in region A', 'goal sent by /cli_a', '/flexarm_learner',
                 'm1', 'nothing moved'):
        assert part in second.reason
    assert arm.running == first


def test_a_released_arm_is_free_for_the_next_motion_with_a_new_id() -> None:
    arm = ownership()
    first = arm.claim('move', 'a', '', COMPENSATOR, 0.0)
    assert arm.release(first.motion_id) == (True, f'ended {first.text()}')
    assert arm.running is None and 'released' in arm.ended
    second = arm.claim('collect', 'b', '', LEARNER, 1.0)
    assert isinstance(second, Motion) and second.motion_id != first.motion_id


def test_only_the_named_motion_is_released_and_force_ends_whichever_runs() -> None:
    arm = ownership()
    first = arm.claim('collect', 'a', '', LEARNER, 0.0)
    released, message = arm.release('m7')
    assert not released and 'does not hold the arm' in message and arm.running == first
    assert arm.release('') == (False, 'no motion named (only a forced release ends whichever '
                                      'runs)')
    released, message = arm.release('', force=True, by='/flexarm_cli_9')
    assert released and arm.running is None
    assert arm.ended == 'collect motion m1 canceled by /flexarm_cli_9'
    assert arm.release('m1')[0] is False       # an ended claim stays ended


def test_a_motion_is_joined_only_while_it_holds_the_arm() -> None:
    arm = ownership()
    calibration = arm.claim('calibrate', 'tool', 'goal sent by /cli', Holder('/cli'), 0.0)
    assert arm.claim('move', 'pose 1', '', COMPENSATOR, 1.0,
                     within=calibration.motion_id) == calibration
    arm.release('', force=True, by='/op')
    refused = arm.claim('move', 'pose 2', '', COMPENSATOR, 2.0, within=calibration.motion_id)
    assert isinstance(refused, Refused) and 'canceled by /op' in refused.reason
    assert arm.running is None                 # refusing a join does not start a motion


def test_a_holder_that_ended_frees_the_arm() -> None:
    arm = ownership()
    held = arm.claim('collect', 'a', '', LEARNER, 0.0)
    assert arm.check(lambda holder: True) is None and arm.running == held
    assert arm.check(lambda holder: holder != LEARNER) == held
    assert arm.running is None and 'ended with its holder /flexarm_learner' in arm.ended


def test_a_claim_without_kind_or_holder_is_refused() -> None:
    arm = ownership()
    assert isinstance(arm.claim('', 'a', '', LEARNER, 0.0), Refused)
    assert isinstance(arm.claim('move', 'a', '', Holder(''), 0.0), Refused)
    assert arm.running is None
