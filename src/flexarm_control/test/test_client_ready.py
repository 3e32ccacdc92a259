"""The client's readiness wait against a server that answers every request late, as a
compensator on an overloaded machine does: the wait ends at the first answer, whichever probe
it answers, instead of waiting for an answer to the latest probe that never comes in time."""
from __future__ import annotations

import threading
import time
from typing import Any

import pytest
import rclpy
from rclpy.action import ActionServer
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from flexarm_control.ros.client import FlexarmClient
from flexarm_core import topics
from flexarm_msgs.action import MoveToPose

pytestmark = [pytest.mark.node]
LATE = 1.5       # [s] each request waits this long before the server handles it
TIMEOUT = 8.0    # [s] the client's wait: five answers' worth


class LateServer(ActionServer):
    """An action server that handles each request it takes ``LATE`` seconds after taking it."""

    async def execute(self, taken_data: Any = None) -> None:
        time.sleep(LATE)
        await super().execute(taken_data)


def test_a_server_answering_each_probe_late_is_ready(domain_id):
    server_context, client_context = Context(), Context()
    rclpy.init(context=server_context, domain_id=domain_id)
    rclpy.init(context=client_context, domain_id=domain_id)
    server = Node('flexarm_late_compensator', context=server_context)
    LateServer(server, MoveToPose, topics.MOVE_TO_POSE, lambda handle: MoveToPose.Result())
    executor = SingleThreadedExecutor(context=server_context)
    executor.add_node(server)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    client = FlexarmClient('flexarm_ready_client', context=client_context)
    try:
        client.wait_until_ready(TIMEOUT, learner=False)    # raises TimeoutError at its deadline
    finally:
        # the server's spin ends first: the probe it handles then still has a client to answer
        executor.shutdown(timeout_sec=5.0)
        spinner.join(timeout=10.0)
        server.destroy_node()
        rclpy.try_shutdown(context=server_context)
        client.destroy_node()
        rclpy.try_shutdown(context=client_context)
