"""``flexarm_recorder``: record flexarm topics into an MCAP bag (rosbag2 layout).

Writes ``<bag_directory>/<bag_name>/<bag_name>.mcap`` with :class:`BagWriter`: messages are
taken raw (serialized CDR) from the wire, so nothing is decoded. Each wanted topic (names or
patterns, :mod:`flexarm_bringup.topic_discovery`) is subscribed once a publisher of it is
discovered (checked every ``discovery_period``), with its type from the graph and a QoS that
matches all its publishers (latched topics such as /learner/model are recorded even if
published before), keep last ``queue_depth`` (deep enough for bursts while Python takes the
messages one by one; the camera's own, smaller depth bounds the memory of queued images).
Log times are wall-clock receive times (so a bag is ordered even before /clock runs);
publish times are the publishers' source timestamps. Message stamps keep the graph's (sim)
time.

Decision: one bag per recorder run. ``flexarm up --record NAME`` records the whole session
in one bag; a trial that wants a bag of its own starts (and stops) a recorder for itself.

Chunks are flushed every ``flush_period`` (wall clock, also under sim time), so after a
SIGKILL the bag holds everything older than about that. SIGINT and SIGTERM close the bag
cleanly: the handlers only stop the spin loop (:func:`spin_until_signalled`), the bag is
closed after spinning stops.

Health on ``/diagnostics``: :func:`recorder_status`, stamped with the graph's time
(:class:`flexarm_core.stamps.GraphTime`: the newest ``/clock`` in a simulated graph, taken
without waking the node; wall time on a real arm): the recorder skips the node's own
``/clock`` subscription, which would wake it once more for each ``/clock`` it records.
"""
from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.topic_endpoint_info import TopicEndpointInfo

from flexarm_bringup.bag_writer import DEFAULT_CHUNK_SIZE, BagWriter, duration_yaml
from flexarm_bringup.topic_discovery import (
    RawHandler,
    RawTopicSubscriber,
    TopicSelection,
    spin_until_signalled,
)
from flexarm_core import topics
from flexarm_core.diagnostics import DiagnosticsPublisher
from flexarm_core.health_report import OK, WARN, Status, status
from flexarm_core.node_params import declare
from flexarm_core.paths import BAGS_DIR
from flexarm_core.stamps import GraphTime

DEFAULT_BAG_DIRECTORY = BAGS_DIR
DRAIN_QUIET, DRAIN_MAX = 0.2, 2.0   # [s] on shutdown: write what arrived, bounded
DEFAULT_TOPICS = [topics.JOINT_STATES, topics.JOINT_COMMANDS, topics.JOINT_TRAJECTORY,
                  topics.CLOCK, topics.CAMERA_INFO,
                  topics.TIP_POSE, topics.TIP_POSE_TRUTH, topics.SAMPLES, topics.MODEL,
                  topics.ACTIVE_MODEL, topics.MODEL_HEALTH, topics.PAYLOAD, topics.OUTCOMES,
                  topics.DIAGNOSTICS, topics.ROBOT_DESCRIPTION, topics.TF, topics.TF_STATIC,
                  topics.TARGET_POSE, topics.COMMANDED_POSE, topics.MEASURED_TIP,
                  topics.TRUE_TIP, topics.SCENE_MARKERS]


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
    """Subscribes raw to the wanted topics as they appear and writes them to one bag."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('flexarm_recorder', **kwargs)
        directory = declare(self, 'bag_directory', str(DEFAULT_BAG_DIRECTORY),
                            'directory holding the bags')
        name = declare(self, 'bag_name', '',
                       'bag (sub-directory and file) name; empty: flexarm_YYYYmmdd_HHMMSS')
        wanted = declare(self, 'topics', DEFAULT_TOPICS,
                         'topics to record: names or fnmatch patterns ("*": all)')
        record_images = declare(self, 'record_images', False,
                                f'also record {topics.CAMERA_IMAGE}')
        discovery_period = declare(self, 'discovery_period', 0.5,
                                   'period of looking for publishers of wanted topics [s]',
                                   bounds=(0.01, 60.0))
        flush_period = declare(self, 'flush_period', 1.0,
                               'period of writing the chunk in progress to disk [s]',
                               bounds=(0.01, 3600.0))
        queue_depth = declare(self, 'queue_depth', 1000,
                              'subscription history depth (keep last) of a topic',
                              bounds=(1, 1000000))
        image_queue_depth = declare(self, 'image_queue_depth', 30,
                                    f'the same for {topics.CAMERA_IMAGE}', bounds=(1, 10000))
        chunk_size = declare(self, 'chunk_size', DEFAULT_CHUNK_SIZE,
                             'MCAP chunk size [bytes]')
        self.writer = BagWriter(Path(directory) / (name or default_bag_name()),
                                chunk_size=chunk_size)
        self.create_timer(flush_period, self.writer.flush,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        selection = TopicSelection(tuple(wanted), record_images, self.get_namespace())
        self.get_logger().info(f'recording {list(wanted)} (images: {record_images}) to '
                               f'{self.writer.path}')
        self.topics = RawTopicSubscriber(self, selection, self._add_topic, 'recording',
                                         discovery_period, queue_depth, image_queue_depth)
        self._diagnostics = DiagnosticsPublisher(self, lambda: [recorder_status(
            self.get_name(), str(self.writer.path), sorted(self.topics.subscriptions),
            sorted(self.topics.left_out), self.writer.message_count)], stamp=GraphTime(self).stamp)

    def _add_topic(self, topic: str, publishers: Sequence[TopicEndpointInfo]) -> RawHandler:
        """Add the topic to the bag; the handler that writes its messages."""
        type_hash = str(publishers[0].topic_type_hash)
        self.writer.add_topic(topic, publishers[0].topic_type,
                              [qos_profile_dict(p.qos_profile) for p in publishers],
                              type_hash=type_hash if type_hash.startswith('RIHS') else '')

        def record(data: bytes, info: Any) -> None:
            self.writer.write(topic, data, time.time_ns(), info['source_timestamp'])

        return record

    def destroy_node(self) -> None:
        """Close the bag (summary, rosbag2 metadata, metadata.yaml), then the node."""
        self.writer.close()
        self.get_logger().info(
            f'closed {self.writer.path}: {self.writer.message_count} messages')
        super().destroy_node()


def _drain(executor: SingleThreadedExecutor, node: RecorderNode) -> None:
    """Write what has already arrived (e.g. the last goal's outcome, published just before
    the graph is stopped): spin until nothing new comes for DRAIN_QUIET, at most DRAIN_MAX."""
    deadline = time.monotonic() + DRAIN_MAX
    count, quiet_since = node.writer.message_count, time.monotonic()
    while time.monotonic() < deadline and time.monotonic() - quiet_since < DRAIN_QUIET:
        executor.spin_once(timeout_sec=0.02)
        if node.writer.message_count != count:
            count, quiet_since = node.writer.message_count, time.monotonic()


def main(args: list[str] | None = None) -> None:
    """Spin until SIGINT/SIGTERM, write what already arrived, then close the bag, destroy
    the node and shut rclpy down."""
    spin_until_signalled(RecorderNode, args, finish=_drain)


if __name__ == '__main__':
    main()
