"""``flexarm_recorder``: record flexarm topics into an MCAP bag (rosbag2 layout).

Subscribes each wanted topic (names or patterns) once a publisher of it is discovered
(:mod:`flexarm_recording.topic_discovery`), takes what arrived in batches, serialized
and never decoded (:class:`flexarm_core.ros.taken.Taken`), and writes it to
``<bag_directory>/<bag_name>/<bag_name>.mcap`` (:mod:`flexarm_recording.bag_writer`).
By default ``/tip_pose`` is recorded only while another node consumes it: a recording does not
make the graph measure. One bag per run, closed cleanly on SIGINT or SIGTERM.

Explained in docs/nodes.md#the-recorder-flexarm_recorder.
"""
from __future__ import annotations

import time
from bisect import bisect_right
from collections.abc import Sequence
from operator import itemgetter
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.exceptions import InvalidHandle
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.topic_endpoint_info import TopicEndpointInfo

from flexarm_core import topics
from flexarm_core.health_report import OK, WARN, Status, status
from flexarm_core.paths import repo_path
from flexarm_core.ros.diagnostics import DiagnosticsPublisher
from flexarm_core.ros.node_main import run
from flexarm_core.ros.node_params import declare
from flexarm_core.ros.stamps import GraphTime
from flexarm_core.ros.taken import Taken
from flexarm_recording.bag_writer import BagWriter, duration_yaml
from flexarm_recording.topic_discovery import (
    RawHandler,
    RawTopicSubscriber,
    TopicSelection,
)

DRAIN_QUIET, DRAIN_MAX = 0.2, 2.0   # [s] on shutdown: write what arrived, bounded


def default_bag_name() -> str:
    """``flexarm_YYYYmmdd_HHMMSS`` of the local time now."""
    return time.strftime('flexarm_%Y%m%d_%H%M%S')


def qos_profile_dict(qos: QoSProfile) -> dict[str, Any]:
    """A publisher's QoS as rosbag2 stores it in ``offered_qos_profiles``."""
    return {
        'history': qos.history.name.lower(),
        'depth': qos.depth,
        'reliability': qos.reliability.name.lower(),
        'durability': qos.durability.name.lower(),
        'deadline': duration_yaml(qos.deadline.nanoseconds),
        'lifespan': duration_yaml(qos.lifespan.nanoseconds),
        'liveliness': qos.liveliness.name.lower(),
        'liveliness_lease_duration': duration_yaml(qos.liveliness_lease_duration.nanoseconds),
        'avoid_ros_namespace_conventions': qos.avoid_ros_namespace_conventions,
    }


def recorder_status(node: str, bag: str, recorded: Sequence[str], left_out: Sequence[str],
                    messages: int) -> Status:
    """``<node>: bag``: the bag's path, the topics recorded and the messages written; WARN
    when a wanted topic is left out (its type cannot be loaded), else OK."""
    values = {'bag': bag, 'topics recorded': len(recorded),
              'recorded': ', '.join(recorded), 'left out': ', '.join(left_out),
              'messages written': messages}
    text = f'{messages} messages of {len(recorded)} topics to {bag}'
    if left_out:
        return status(node, 'bag', WARN, f'{text}; not recordable: {", ".join(left_out)}',
                      values)
    return status(node, 'bag', OK, text, values)


class RecorderNode(Node):
    """Subscribes raw to the wanted topics as they appear, takes what arrived every
    ``take_period`` and writes it to one bag."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('flexarm_recorder', **kwargs)
        directory = repo_path(declare(self, 'bag_directory', 'config/recorder.yaml'))
        name = declare(self, 'bag_name', 'config/recorder.yaml')
        wanted = declare(self, 'topics', 'config/recorder.yaml')
        record_images = declare(self, 'record_images', 'config/recorder.yaml')
        self._passive = declare(self, 'passive_measurements', 'config/recorder.yaml')
        discovery_period = declare(self, 'discovery_period', 'config/recorder.yaml')
        take_period = declare(self, 'take_period', 'config/recorder.yaml')
        flush_period = declare(self, 'flush_period', 'config/recorder.yaml')
        queue_depth = declare(self, 'queue_depth', 'config/recorder.yaml')
        image_queue_depth = declare(self, 'image_queue_depth', 'config/recorder.yaml')
        chunk_size = declare(self, 'chunk_size', 'config/recorder.yaml')
        compression = declare(self, 'compression', 'config/recorder.yaml')
        self.writer = BagWriter(directory / (name or default_bag_name()),
                                chunk_size=chunk_size, compression=compression)
        self._pending: list[tuple[int, str, bytes, int]] = []   # taken, not yet written
        self._consumed: dict[str, int] = {}     # passes in a row another node consumed it
        self._measured = topics.absolute(topics.TIP_POSE, self.get_namespace())
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(take_period, self.take, clock=steady)
        self.create_timer(flush_period, self.flush, clock=steady)
        selection = TopicSelection(tuple(wanted), record_images, self.get_namespace())
        self.get_logger().info(f'recording {list(wanted)} (images: {record_images}) to '
                               f'{self.writer.path}')
        self.topics = RawTopicSubscriber(self, selection, self._add_topic, 'recording',
                                         discovery_period, queue_depth, image_queue_depth,
                                         active=self._active, callback_group=Taken())
        self._diagnostics = DiagnosticsPublisher(self, lambda: [recorder_status(
            self.get_name(), str(self.writer.path), sorted(self.topics.subscriptions),
            sorted(self.topics.left_out), self.writer.message_count)], stamp=GraphTime(self).stamp)

    def _add_topic(self, topic: str, publishers: Sequence[TopicEndpointInfo]) -> RawHandler:
        """Add the topic to the bag; the handler that writes a message (its subscription is
        taken, so only a caller outside the executor would use it)."""
        type_hash = str(publishers[0].topic_type_hash)
        self.writer.add_topic(topic, publishers[0].topic_type,
                              [qos_profile_dict(p.qos_profile) for p in publishers],
                              type_hash=type_hash if type_hash.startswith('RIHS') else '')

        def record(data: bytes, info: Any) -> None:
            self.writer.write(topic, data, time.time_ns(), info['source_timestamp'])

        return record

    def _active(self, topic: str) -> bool:
        """Whether the topic is to be subscribed now (each discovery pass): all but the
        measured tip, and that one too unless ``passive_measurements`` (docs/nodes.md)."""
        if not self._passive or topic != self._measured:
            return True
        me = (self.get_name(), self.get_namespace())
        consumed = any((info.node_name, info.node_namespace) != me
                       for info in self.get_subscriptions_info_by_topic(topic))
        self._consumed[topic] = self._consumed.get(topic, 0) + 1 if consumed else 0
        subscribed = getattr(self, 'topics', None)      # None: the first pass, at start
        if not consumed and subscribed is not None and topic in subscribed.subscriptions:
            self._take_topic(topic, subscribed.subscriptions[topic])    # before it goes
        return self._consumed[topic] >= 2

    def _take_topic(self, topic: str, subscription: Any) -> None:
        """Move what arrived on one subscription to the pending messages."""
        pending = self._pending
        try:
            with subscription.handle:
                take = subscription.handle.take_message
                while (taken := take(subscription.msg_type, True)) is not None:
                    data, info = taken
                    pending.append((info['received_timestamp'] or time.time_ns(), topic,
                                    data, info['source_timestamp']))
        except InvalidHandle:           # destroyed meanwhile (shutdown)
            pass

    def take(self) -> int:
        """Take what arrived on every topic and write it in receive order, but what was
        received after this call began (that waits for the next, so log times never step
        back); the messages written."""
        cutoff = time.time_ns()
        for topic, subscription in list(self.topics.subscriptions.items()):
            self._take_topic(topic, subscription)
        if not self._pending:
            return 0
        self._pending.sort(key=itemgetter(0))
        split = bisect_right(self._pending, cutoff, key=itemgetter(0))
        ready, self._pending = self._pending[:split], self._pending[split:]
        write = self.writer.write
        for received, topic, data, published in ready:
            write(topic, data, received, published)
        return len(ready)

    def flush(self) -> None:
        """Take and write what arrived, then write the chunk in progress to disk."""
        self.take()
        self.writer.flush()

    def destroy_node(self) -> None:
        """Write what is pending, close the bag (summary, rosbag2 metadata, metadata.yaml),
        then destroy the node."""
        self.take()
        for received, topic, data, published in sorted(self._pending, key=itemgetter(0)):
            self.writer.write(topic, data, received, published)
        self._pending = []
        self.writer.close()
        self.get_logger().info(
            f'closed {self.writer.path}: {self.writer.message_count} messages')
        super().destroy_node()


def _drain(executor: SingleThreadedExecutor, node: RecorderNode) -> None:
    """Write what has already arrived (e.g. the last goal's outcome, published just before
    the graph is stopped): take until nothing new comes for DRAIN_QUIET, at most DRAIN_MAX
    (spinning meanwhile: a latched topic found now is still subscribed)."""
    deadline = time.monotonic() + DRAIN_MAX
    quiet_since = time.monotonic()
    while time.monotonic() < deadline and time.monotonic() - quiet_since < DRAIN_QUIET:
        executor.spin_once(timeout_sec=0.02)
        if node.take() or node._pending:
            quiet_since = time.monotonic()


def main(args: list[str] | None = None) -> None:
    """Spin until SIGINT/SIGTERM, write what already arrived, then close the bag, destroy
    the node and shut rclpy down."""
    run(RecorderNode, args, finish=_drain)


if __name__ == '__main__':
    main()
