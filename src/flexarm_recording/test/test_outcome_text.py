"""Outcomes in words: result codes by name, hints, operator units."""
import math

import pytest

from flexarm_msgs.action import CollectSamples, MoveToPose
from flexarm_recording.results.outcome_text import (
    COLLECT_HINTS,
    EXIT_MEANINGS,
    MOVE_HINTS,
    Exit,
    code_name,
    code_names,
    failure_text,
    human_units,
    is_busy,
    pose_text,
)


def test_codes_are_named_by_their_own_result_class():
    assert code_name(MoveToPose.Result, -2) == 'UNREACHABLE'
    assert code_name(CollectSamples.Result, -2) == 'CANCELED'       # same number, other action
    assert code_name(MoveToPose.Result, -99) == '-99'
    assert code_names(MoveToPose.Result)[MoveToPose.Result.OUTSIDE_LEARNED_DATA] == (
        'OUTSIDE_LEARNED_DATA')


@pytest.mark.parametrize('result_type, hints', [(MoveToPose.Result, MOVE_HINTS),
                                                (CollectSamples.Result, COLLECT_HINTS)])
def test_every_failure_code_has_a_hint(result_type, hints):
    failures = set(code_names(result_type).values()) - {'SUCCESSFUL'}
    assert failures == set(hints)


def test_failure_says_the_name_whether_the_arm_moved_and_what_to_do():
    text = failure_text('UNREACHABLE', 'pose (x=0.005 m, y=0 m, phi=0 deg) is out of reach',
                        MOVE_HINTS, moved=False)
    first, hint = text.split('\n')
    assert first == ('refused (UNREACHABLE; nothing moved): pose (x=5 mm, y=0 mm, phi=0 deg) '
                     'is out of reach')
    assert hint == f'  what to do: {MOVE_HINTS["UNREACHABLE"]}'
    assert failure_text('TOLERANCE_NOT_MET', '', MOVE_HINTS, moved=True).startswith(
        'failed (TOLERANCE_NOT_MET): no reason given\n')
    assert failure_text('-99', 'odd', MOVE_HINTS, moved=True) == 'failed (-99): odd'


@pytest.mark.parametrize('si, human', [
    ('x=1.45 m', 'x=1450 mm'), ('joint2 = 0.6000 m outside', 'joint2 = 600 mm outside'),
    ('-1e-05 m', '-0.01 mm'), ('phi 1.5707963267948966 rad', 'phi 90 deg'),
    ('0.05 mm, 3 min, 2 m/s, item 3', '0.05 mm, 3 min, 2 m/s, item 3'),   # left alone
])
def test_si_figures_are_said_in_mm_and_deg(si, human):
    assert human_units(si) == human


def test_pose_text_and_busy():
    assert pose_text((1.45, -0.15, math.radians(-45))) == (
        'x=1450.00 mm, y=-150.00 mm, phi=-45.000 deg')
    assert is_busy('busy: another goal is executing (one at a time)')
    assert is_busy('training failed: busy: a collection is running')
    assert not is_busy('not busy') and not is_busy('failed: busybox: missing')


def test_every_exit_code_has_a_meaning_and_they_differ():
    assert set(EXIT_MEANINGS) == set(Exit)
    assert len({int(e) for e in Exit}) == len(Exit) and Exit.USAGE == 2  # argparse's own
