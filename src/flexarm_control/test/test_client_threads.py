"""The scriptable client used from two threads at once (a goal waited for in one, a cancel sent
from another, as a stop button does): they take turns in its executor instead of entering it
together, which rclpy refuses ("generator already executing") and which aborted a process."""
from __future__ import annotations

import threading

import pytest
import rclpy
from rclpy.context import Context
from rclpy.task import Future

from flexarm_control.ros.client import FlexarmClient

pytestmark = [pytest.mark.node]
WAITERS = 4
SECONDS = 1.0     # each waiter serves the client this long, in short slices as its waits do


def test_two_threads_waiting_on_one_client_take_turns(domain_id):
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    client = FlexarmClient('flexarm_threads_client', context=context)
    errors: list[BaseException] = []

    def wait() -> None:
        never = Future()
        try:
            for i in range(round(SECONDS / 0.01)):    # waits on a future, and plain spins
                client.serve(never if i % 2 else None, 0.01)
        except BaseException as error:     # noqa: BLE001 - what a thread raised, reported below
            errors.append(error)

    try:
        threads = [threading.Thread(target=wait) for _ in range(WAITERS)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(timeout=30.0)
        assert not any(thread.is_alive() for thread in threads)
        assert errors == []
    finally:
        client.destroy_node()
        rclpy.try_shutdown(context=context)
