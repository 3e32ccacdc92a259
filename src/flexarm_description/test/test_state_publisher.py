"""What the state publisher subscribes to for whom: its inputs on demand (pure)."""
from __future__ import annotations

from flexarm_core import topics
from flexarm_description.state_publisher_node import UNKNOWN_NODE, not_viewers, wanted_inputs

NOTHING = {'joints': False, 'true': False, 'measured': False}


def test_an_unwatched_publisher_takes_nothing() -> None:
    assert wanted_inputs({}, {}) == NOTHING
    assert wanted_inputs({topics.TF: 0, topics.MEASURED_TIP: 0}, {}) == NOTHING


def test_a_viewer_of_tf_asks_for_every_frame_the_measured_tip_too() -> None:
    assert wanted_inputs({topics.TF: 1}, {topics.TF: 0}) == {
        'joints': True, 'true': True, 'measured': True}


def test_a_recorder_of_tf_does_not_make_the_graph_measure() -> None:
    """The joint and true-tip frames cost little; the measured tip runs the camera."""
    assert wanted_inputs({topics.TF: 1}, {topics.TF: 1}) == {
        'joints': True, 'true': True, 'measured': False}
    recording_all = {topics.TF: 1, topics.MEASURED_TIP: 1, topics.TRUE_TIP: 1}
    assert wanted_inputs(recording_all, recording_all) == {
        'joints': True, 'true': True, 'measured': False}


def test_a_viewer_beside_a_recorder_asks_for_the_measured_tip() -> None:
    assert wanted_inputs({topics.TF: 2}, {topics.TF: 1})['measured']
    assert wanted_inputs({topics.TF: 1, topics.MEASURED_TIP: 1},
                         {topics.TF: 1})['measured']


def test_each_tip_alone_asks_for_its_own_input_only() -> None:
    assert wanted_inputs({topics.TRUE_TIP: 1}, {}) == {
        'joints': False, 'true': True, 'measured': False}
    assert wanted_inputs({topics.MEASURED_TIP: 1}, {}) == {
        'joints': False, 'true': False, 'measured': True}


def test_a_subscriber_whose_node_is_not_known_yet_is_no_viewer_until_it_is() -> None:
    """A recorder's subscription is matched a moment before its node's name is known: it must
    not make the graph measure meanwhile."""
    recorders = {'flexarm_recorder'}
    assert not_viewers(1, [UNKNOWN_NODE], recorders) == 1
    assert not_viewers(2, ['rviz'], recorders) == 1            # one not in the graph yet
    assert not_viewers(1, ['flexarm_recorder'], recorders) == 1
    assert not_viewers(2, ['flexarm_recorder', 'rviz'], recorders) == 1
    assert not wanted_inputs({topics.TF: 1}, {topics.TF: not_viewers(
        1, [UNKNOWN_NODE], recorders)})['measured']
