"""``flexarm_foxglove``: the live graph in Foxglove, over the Foxglove WebSocket protocol.

Serves the wanted topics (all but the camera images by default) as it discovers them
(:mod:`flexarm_recording.topic_discovery`, as the recorder does), each as a channel of
raw ``cdr`` messages with its ``ros2msg`` schema (:mod:`flexarm_recording.bag_schema`),
subscribed only while a client watches it; it only sends, so Foxglove can look at the arm but
not command it. The server is the ``foxglove`` SDK's, behind
:class:`~flexarm_viz.foxglove_front.SubprotocolFront`; once both listen the node logs
:func:`announcement`, which ``flexarm up`` waits for.

Explained in docs/nodes.md#foxglove-flexarm_foxglove.
"""
from __future__ import annotations

import os
import re
import time
from collections.abc import Sequence
from typing import Any

import foxglove
from rclpy.node import Node
from rclpy.topic_endpoint_info import TopicEndpointInfo

from flexarm_core.ros.node_main import run
from flexarm_core.ros.node_params import declare
from flexarm_recording.bag_schema import message_definition
from flexarm_recording.topic_discovery import (
    RawHandler,
    RawTopicSubscriber,
    TopicSelection,
)
from flexarm_viz.foxglove_front import SubprotocolFront

SERVER_NAME = 'flexarm'
LISTENING = 'Foxglove WebSocket server listening on'


def announcement(url: str, pid: int) -> str:
    """The log line by which the node of process ``pid`` says that ``url`` accepts clients."""
    return f'{LISTENING} {url} (process {pid})'


def listening_url(log: str, pid: int) -> str | None:
    """The URL the node of process ``pid`` announced in its log (:func:`announcement`), or
    None before it did. The pid tells a restarted node's line from its predecessor's (a
    node's log file is appended to)."""
    found = re.search(rf'{re.escape(LISTENING)} (ws://\S+) \(process {pid}\)', log)
    return None if found is None else found[1]


def ros2_channel(topic: str, type_name: str, context: foxglove.Context) -> foxglove.Channel:
    """A Foxglove channel of ``cdr`` messages of ``pkg/msg/Type`` with its ``ros2msg``
    schema; FileNotFoundError or ValueError when the type's ``.msg`` file is not found."""
    schema = foxglove.Schema(name=type_name, encoding='ros2msg',
                             data=message_definition(type_name).encode())
    return foxglove.Channel(topic, schema=schema, message_encoding='cdr', context=context)


class FoxgloveNode(Node):
    """Serves the selected topics, raw, to Foxglove clients as they are discovered."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('flexarm_foxglove', **kwargs)
        host = declare(self, 'host', 'config/foxglove.yaml', read_only=True)
        port = declare(self, 'port', 'config/foxglove.yaml', read_only=True)
        wanted = declare(self, 'topics', 'config/foxglove.yaml')
        images = declare(self, 'images', 'config/foxglove.yaml')
        discovery_period = declare(self, 'discovery_period', 'config/foxglove.yaml')
        queue_depth = declare(self, 'queue_depth', 'config/foxglove.yaml')
        image_queue_depth = declare(self, 'image_queue_depth', 'config/foxglove.yaml')
        self._sdk_context = foxglove.Context()
        self.server = foxglove.start_server(name=SERVER_NAME, host='127.0.0.1', port=0,
                                            context=self._sdk_context)
        try:
            self.front = SubprotocolFront(host, port, self.server.port)
        except OSError as err:          # e.g. the port is taken
            self.server.stop()
            raise RuntimeError(f'cannot serve Foxglove on {host}:{port}: {err}') from None
        self.channels: dict[str, foxglove.Channel] = {}
        # both listen now (the SDK's server and the front bound and listen when made)
        url = f'ws://{host}:{self.front.port}'
        self.get_logger().info(f'{announcement(url, os.getpid())}, serving {list(wanted)} '
                               f'(images: {images})')
        selection = TopicSelection(tuple(wanted), images, self.get_namespace())
        self.topics = RawTopicSubscriber(self, selection,
                                         self._add_channel, 'serving', discovery_period,
                                         queue_depth, image_queue_depth, self._watched)

    def _watched(self, topic: str) -> bool:
        """Whether a client subscribes to the topic's channel."""
        return self.channels[topic].has_sinks()

    def _add_channel(self, topic: str, publishers: Sequence[TopicEndpointInfo]) -> RawHandler:
        """Advertise the topic's channel; the handler that sends its messages."""
        channel = self.channels[topic] = ros2_channel(topic, publishers[0].topic_type,
                                                      self._sdk_context)

        def send(data: bytes, _info: Any) -> None:
            channel.log(data, log_time=time.time_ns())

        return send

    def destroy_node(self) -> None:
        """Stop the server (clients see it close, through the front), its front, then the
        node."""
        self.server.stop()
        self.front.stop()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Serve until SIGINT/SIGTERM, then stop the server and shut rclpy down."""
    run(FoxgloveNode, args)


if __name__ == '__main__':
    main()
