"""Raw subscriptions to graph topics as their publishers appear: what the recorder and the
Foxglove server share.

:class:`TopicSelection` says which topics are wanted (names, or ``fnmatch`` patterns such as
``*``); :class:`RawTopicSubscriber` looks for publishers of them every discovery period and
subscribes to each once found, raw (serialized CDR, nothing decoded), with its type from the
graph and a QoS that matches all its publishers, as ``ros2 bag record`` does: reliable if they
all are, transient local if they all are (so latched topics such as /learner/model and
/camera/camera_info are received even if published before), keep last ``queue_depth``.

Decisions: a pattern never takes /camera/image_raw (~9 MB/s at 30 Hz): the images come only
when named or asked for; nor hidden topics (actions' ``_action/*``), as ``ros2 topic list``
hides them. A topic whose type cannot be loaded (no Python class, no ``.msg`` file) is left
out once, with an error in the log.
"""
from __future__ import annotations

import importlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from fnmatch import fnmatchcase
from typing import Any

from rclpy.callback_groups import CallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.topic_endpoint_info import TopicEndpointInfo

from flexarm_core import topics

# A handler of one topic's raw messages: (serialized message, message info).
RawHandler = Callable[[bytes, Any], None]
# Called once per topic found: returns its handler; FileNotFoundError or ValueError (no
# .msg file, not a message type) leaves the topic out.
Prepare = Callable[[str, Sequence[TopicEndpointInfo]], RawHandler]
_WILDCARDS = frozenset('*?[')


@dataclass(frozen=True)
class TopicSelection:
    """Wanted topics: exact names and ``fnmatch`` patterns; the camera images only if named
    or if ``images``. Relative names and patterns are taken in ``namespace`` (the node's: an
    arm's recorder records that arm), absolute ones as they are."""

    patterns: tuple[str, ...]
    images: bool = False
    namespace: str = ''

    @property
    def image_topic(self) -> str:
        return topics.absolute(topics.CAMERA_IMAGE, self.namespace)

    def select(self, names: Iterable[str]) -> list[str]:
        """The wanted ones of ``names`` (the graph's topics, absolute), in their order; named
        topics first, found in the graph or not."""
        patterns = [topics.absolute(p, self.namespace) for p in self.patterns]
        named = [p for p in patterns if not _WILDCARDS & set(p)]
        wildcards = [p for p in patterns if _WILDCARDS & set(p)]
        chosen = [*named, *([self.image_topic] if self.images else [])]
        chosen += [n for n in names if n != self.image_topic and not is_hidden(n)
                   and any(fnmatchcase(n, w) for w in wildcards)]
        return list(dict.fromkeys(chosen))


def is_hidden(name: str) -> bool:
    """A hidden ROS name: one of its parts starts with ``_`` (e.g. actions' ``_action/*``)."""
    return any(part.startswith('_') for part in name.split('/'))


def message_class(type_name: str) -> type:
    """The Python message class of ``pkg/msg/Type``."""
    package, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


def request_qos(publishers: Sequence[TopicEndpointInfo], depth: int) -> QoSProfile:
    """A subscription QoS compatible with all publishers that keeps what they offer."""
    offered = [p.qos_profile for p in publishers]
    reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
    latched = all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


class RawTopicSubscriber:
    """Subscribes ``node`` raw to the selected topics as their publishers are discovered.

    ``prepare(topic, publishers)`` is called once per topic, when it is found, and gives the
    handler of its messages; ``purpose`` ('recording', 'serving') words the log. With
    ``active``, a found topic is subscribed only while ``active(topic)`` holds (checked each
    discovery pass) and unsubscribed when it stops holding; without it, always. The
    subscriptions are made in ``callback_group`` (None: the node's default), e.g. one whose
    messages the owner takes itself instead of the executor calling the handler.
    """

    def __init__(self, node: Node, selection: TopicSelection, prepare: Prepare, purpose: str,
                 period: float, queue_depth: int, image_queue_depth: int,
                 active: Callable[[str], bool] | None = None,
                 callback_group: CallbackGroup | None = None) -> None:
        self._node, self._selection, self._prepare = node, selection, prepare
        self._purpose, self._active, self._group = purpose, active, callback_group
        self._queue_depth, self._image_queue_depth = queue_depth, image_queue_depth
        self._found: dict[str, tuple[type, RawHandler]] = {}
        self.subscriptions: dict[str, Any] = {}
        self.left_out: set[str] = set()
        node.create_timer(period, self.discover, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.discover()

    def discover(self) -> None:
        """Prepare every selected topic that has publishers, then (un)subscribe as wanted."""
        names = [name for name, _ in self._node.get_topic_names_and_types()]
        for topic in self._selection.select(names):
            if topic in self.left_out:
                continue
            if topic not in self._found and not self._find(topic):
                continue
            wanted = self._active is None or self._active(topic)
            if wanted and topic not in self.subscriptions:
                self._subscribe(topic)
            elif not wanted and topic in self.subscriptions:
                self._node.destroy_subscription(self.subscriptions.pop(topic))

    def _find(self, topic: str) -> bool:
        """Whether the topic has publishers and was prepared (else it is left out)."""
        publishers = self._node.get_publishers_info_by_topic(topic)
        if not publishers:
            return False
        type_name = publishers[0].topic_type
        try:
            self._found[topic] = (message_class(type_name), self._prepare(topic, publishers))
        except (ImportError, AttributeError, FileNotFoundError, ValueError) as err:
            self.left_out.add(topic)
            self._node.get_logger().error(f'not {self._purpose} {topic}: {err}')
            return False
        self._node.get_logger().info(f'{self._purpose} {topic} ({type_name})')
        return True

    def _subscribe(self, topic: str) -> None:
        publishers = self._node.get_publishers_info_by_topic(topic)
        if not publishers:          # gone meanwhile: next pass
            return
        message_type, handler = self._found[topic]
        depth = (self._image_queue_depth if topic == self._selection.image_topic
                 else self._queue_depth)
        self.subscriptions[topic] = self._node.create_subscription(
            message_type, topic, handler, request_qos(publishers, depth), raw=True,
            callback_group=self._group)
