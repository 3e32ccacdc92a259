"""``flexarm_recorder``: record flexarm topics into an MCAP bag (rosbag2 layout).

Writes ``<bag_directory>/<bag_name>/<bag_name>.mcap`` with :class:`BagWriter`: messages are
taken raw (serialized CDR) from the wire, so nothing is decoded. Each wanted topic is
subscribed once a publisher of it is discovered (checked every ``discovery_period``), with
its type from the graph and a QoS that matches all its publishers, as ``ros2 bag record``
does: reliable if they all are, transient local if they all are (so latched topics such as
/learner/model and /camera/camera_info are recorded even if published before), keep last
``queue_depth`` (deep enough for bursts while Python takes the messages one by one; the
camera's own, smaller depth bounds the memory of queued images). Log times are wall-clock
receive times (so a bag is ordered even before /clock runs); publish times are the
publishers' source timestamps. Message stamps keep the graph's (sim) time.

Decision: one bag per recorder run. ``flexarm up --record NAME`` records the whole session
in one bag; a trial that wants a bag of its own starts (and stops) a recorder for itself.

Chunks are flushed every ``flush_period`` (wall clock, also under sim time), so after a
SIGKILL the bag holds everything older than about that. SIGINT and SIGTERM close the bag
cleanly: the handlers only stop the spin loop, the bag is closed after spinning stops.
"""
from __future__ import annotations

import importlib
import signal
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.topic_endpoint_info import TopicEndpointInfo

from flexarm_bringup.bag_writer import DEFAULT_CHUNK_SIZE, BagWriter, duration_yaml
from flexarm_control import topics
from flexarm_control.node_params import declare
from flexarm_control.paths import BAGS_DIR

DEFAULT_BAG_DIRECTORY = BAGS_DIR
DRAIN_QUIET, DRAIN_MAX = 0.2, 2.0   # [s] on shutdown: write what arrived, bounded
DEFAULT_TOPICS = [topics.JOINT_STATES, topics.JOINT_COMMANDS, topics.CLOCK, topics.CAMERA_INFO,
                  topics.TIP_POSE, topics.TIP_POSE_TRUTH, topics.SAMPLES, topics.MODEL,
                  topics.OUTCOMES]


def default_bag_name() -> str:
    """``flexarm_YYYYmmdd_HHMMSS`` of the local time now."""
    return time.strftime('flexarm_%Y%m%d_%H%M%S')


def message_class(type_name: str) -> type:
    """The Python message class of ``pkg/msg/Type``."""
    package, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


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


def request_qos(publishers: Sequence[TopicEndpointInfo], depth: int) -> QoSProfile:
    """A subscription QoS compatible with all publishers that keeps what they offer."""
    offered = [p.qos_profile for p in publishers]
    reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
    latched = all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


class RecorderNode(Node):
    """Subscribes raw to the wanted topics as they appear and writes them to one bag."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('flexarm_recorder', **kwargs)
        directory = declare(self, 'bag_directory', str(DEFAULT_BAG_DIRECTORY),
                            'directory holding the bags')
        name = declare(self, 'bag_name', '',
                       'bag (sub-directory and file) name; empty: flexarm_YYYYmmdd_HHMMSS')
        wanted = declare(self, 'topics', DEFAULT_TOPICS, 'topics to record')
        record_images = declare(self, 'record_images', False,
                                f'also record {topics.CAMERA_IMAGE}')
        discovery_period = declare(self, 'discovery_period', 0.5,
                                   'period of looking for publishers of wanted topics [s]')
        flush_period = declare(self, 'flush_period', 1.0,
                               'period of writing the chunk in progress to disk [s]')
        self._queue_depth = declare(self, 'queue_depth', 1000,
                                    'subscription history depth (keep last) of a topic')
        self._image_queue_depth = declare(self, 'image_queue_depth', 30,
                                          f'the same for {topics.CAMERA_IMAGE}')
        chunk_size = declare(self, 'chunk_size', DEFAULT_CHUNK_SIZE,
                             'MCAP chunk size [bytes]')
        self._wanted = list(dict.fromkeys(
            [*wanted, *([topics.CAMERA_IMAGE] if record_images else [])]))
        self.writer = BagWriter(Path(directory) / (name or default_bag_name()),
                                chunk_size=chunk_size)
        self._subscribed: dict[str, Any] = {}
        self._unrecordable: set[str] = set()        # no .msg file found for their type
        wall = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(discovery_period, self._discover, clock=wall)
        self.create_timer(flush_period, self.writer.flush, clock=wall)
        self.get_logger().info(f'recording {self._wanted} to {self.writer.path}')
        self._discover()

    def _discover(self) -> None:
        for topic in self._wanted:
            if topic in self._subscribed or topic in self._unrecordable:
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if publishers:
                self._subscribe(topic, publishers)

    def _subscribe(self, topic: str, publishers: Sequence[TopicEndpointInfo]) -> None:
        type_name = publishers[0].topic_type
        type_hash = str(publishers[0].topic_type_hash)
        try:
            self.writer.add_topic(topic, type_name, [qos_profile_dict(p.qos_profile)
                                                     for p in publishers],
                                  type_hash=type_hash if type_hash.startswith('RIHS') else '')
        except (FileNotFoundError, ValueError) as err:
            self._unrecordable.add(topic)
            self.get_logger().error(f'not recording {topic}: {err}')
            return

        def record(data: bytes, info: Any) -> None:
            self.writer.write(topic, data, time.time_ns(), info['source_timestamp'])

        self._subscribed[topic] = self.create_subscription(
            message_class(type_name), topic, record,
            request_qos(publishers, self._image_queue_depth if topic == topics.CAMERA_IMAGE
                        else self._queue_depth), raw=True)
        self.get_logger().info(f'recording {topic} ({type_name})')

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
    """Spin until SIGINT/SIGTERM, then close the bag, destroy the node and shut rclpy down.

    The signal handlers only set a flag: shutting the context down from a handler while the
    executor is inside a wait or a raw take crashed the process (SIGSEGV) now and then.
    """
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    node = RecorderNode()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
        _drain(executor, node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.remove_node(node)
        node.destroy_node()
        executor.shutdown(timeout_sec=1.0)
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
