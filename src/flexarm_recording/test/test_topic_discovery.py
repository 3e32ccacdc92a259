"""Which topics the recorder and the Foxglove server take, and the classes they load."""
from __future__ import annotations

import pytest

from flexarm_core import topics
from flexarm_recording.topic_discovery import TopicSelection, message_class

IMAGE, INFO, TIP, MODEL = (topics.absolute(t) for t in (
    topics.CAMERA_IMAGE, topics.CAMERA_INFO, topics.TIP_POSE, topics.MODEL))
GRAPH = ['/clock', IMAGE, INFO, TIP, '/tf', '/move_to_pose/_action/status', '/scene/markers',
         '/rosout']


def test_a_wildcard_takes_every_topic_but_the_images_and_the_hidden_ones() -> None:
    assert TopicSelection(('*',)).select(GRAPH) == [
        '/clock', INFO, TIP, '/tf', '/scene/markers', '/rosout']
    assert TopicSelection(('/move_to_pose/_action/status',)).select([]) == [
        '/move_to_pose/_action/status']


def test_the_images_come_when_asked_for_or_named() -> None:
    assert IMAGE in TopicSelection(('*',), images=True).select(GRAPH)
    assert TopicSelection((topics.CAMERA_IMAGE,)).select(GRAPH) == [IMAGE]


def test_named_topics_are_wanted_before_they_appear_and_patterns_match_names() -> None:
    selection = TopicSelection((topics.MODEL, '/scene/*', topics.TIP_POSE))
    assert selection.select(GRAPH) == [MODEL, TIP, '/scene/markers']
    assert selection.select([]) == [MODEL, TIP]
    assert TopicSelection((topics.TIP_POSE,), images=True).select([]) == [TIP, IMAGE]
    assert TopicSelection(('/t?',)).select(GRAPH) == ['/tf']


def test_relative_names_and_patterns_are_the_arms_absolute_ones_as_they_are() -> None:
    graph = ['/clock', '/arm1/tip_pose', '/arm1/camera/image_raw', '/arm2/tip_pose']
    arm1 = TopicSelection(('*', '/clock'), namespace='arm1')
    assert arm1.select(graph) == ['/clock', '/arm1/tip_pose']
    assert arm1.image_topic == '/arm1/camera/image_raw'
    assert TopicSelection((topics.TIP_POSE,), True, '/arm2').select([]) == [
        '/arm2/tip_pose', '/arm2/camera/image_raw']


def test_message_class_loads_a_message_and_fails_as_the_subscriber_expects() -> None:
    from flexarm_msgs.msg import TipPose

    assert message_class('flexarm_msgs/msg/TipPose') is TipPose
    with pytest.raises(ImportError):
        message_class('no_such_msgs/msg/Thing')
    with pytest.raises(AttributeError):
        message_class('flexarm_msgs/msg/NoSuchThing')
