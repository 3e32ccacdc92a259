"""Shared fixtures of node-level tests.

Each test that starts nodes gets its own ROS_DOMAIN_ID (reserved through
ros-jazzy-domain-coordinator, so parallel test runs on one machine do not talk to each other),
starts node processes exactly as ``flexarm up`` does (:mod:`flexarm_bringup.launcher`), and
kills them on teardown. Every wait in a test is bounded.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest


@pytest.fixture
def domain_id(monkeypatch: pytest.MonkeyPatch) -> Iterator[int]:
    """A ROS domain of this test's own; also set for in-process rclpy contexts."""
    from domain_coordinator import domain_id as reserve

    with reserve() as did:
        monkeypatch.setenv('ROS_DOMAIN_ID', str(did))
        monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        yield did


@pytest.fixture
def launch(domain_id: int, tmp_path: Path) -> Iterator[Callable[..., Any]]:
    """``launch(name, **parameters)`` starts the node ``name`` of config/graph.yaml.

    ``robot`` picks the controller entry of graph.yaml (default ``sim``). All nodes started
    by the test are stopped (SIGINT, then SIGKILL) when it ends.
    """
    from flexarm_bringup.launcher import NodeProcess, load_graph, load_optional, ros_env, stop_all

    started: list[NodeProcess] = []

    def start(name: str, robot: str = 'sim', **parameters: Any) -> NodeProcess:
        specs = {**load_optional(), **{s.name: s for s in load_graph(robot)}}
        node = NodeProcess(specs[name], ros_env(domain_id, tmp_path / 'ros_log'),
                           tmp_path / f'{name}.log', parameters)
        node.start()
        started.append(node)
        return node

    yield start
    stop_all(started, timeout=5.0)


@pytest.fixture
def ros_node(domain_id: int, request: pytest.FixtureRequest) -> Iterator[Any]:
    """An rclpy node in its own context on the test's domain, spun in a background thread.

    Parameters of the node: ``@pytest.mark.parametrize('ros_node', [{'use_sim_time': True}],
    indirect=True)``.
    """
    import threading

    import rclpy
    from rclpy.context import Context
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.parameter import Parameter

    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = rclpy.create_node('test_client', context=context, parameter_overrides=[
        Parameter(name, value=value) for name, value in getattr(request, 'param', {}).items()])
    executor = MultiThreadedExecutor(context=context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    try:
        yield node
    finally:
        executor.shutdown(timeout_sec=2.0)
        for waitable in list(node.waitables):   # a test's action servers: destroy_node
            waitable.destroy()                   # leaves them, and the node, alive
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        thread.join(timeout=2.0)


@pytest.fixture
def wait_for() -> Callable[..., Any]:
    """``wait_for(condition, timeout, what)``: bounded polling for tests."""
    return _wait_for


def _wait_for(condition: Callable[[], Any], timeout: float, what: str) -> Any:
    """Poll ``condition`` until it returns something truthy; fail the test after ``timeout``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.02)
    pytest.fail(f'timed out after {timeout:.1f} s waiting for {what}')


@pytest.fixture
def write_dataset() -> Callable[..., None]:
    """``write_dataset(path, count=12, bad=None)``: a dataset file of a smooth deflection at
    ``count`` random joints; sample ``bad`` is 10 mm off."""
    return _write_dataset


def _write_dataset(path: Path, count: int = 12, bad: int | None = None) -> None:
    import numpy as np

    from flexarm_control.dataset import DatasetWriter, Sample

    joints = np.random.default_rng(0).uniform([-0.3, 0.5, -1.5, -1.0], [0.3, 0.8, 0.3, 1.0],
                                               (count, 4))
    with DatasetWriter(path) as writer:
        for i, q in enumerate(joints):
            deflection = np.array([1e-3 * q[0], -0.01 * q[1], 1e-3 * q[3]])
            if i == bad:
                deflection[:2] += [0.006, -0.008]
            writer.append(Sample(i, q, 0.0, np.zeros(3), deflection, deflection, 6, 1e-5))


@pytest.fixture
def ready_client(domain_id: int) -> Iterator[Callable[..., Any]]:
    """``ready_client(**what)``: a FlexarmClient in a context of its own on the test's domain,
    after ``wait_until_ready(timeout=30, **what)``; destroyed when the test ends."""
    import rclpy
    from rclpy.context import Context

    from flexarm_control.client import FlexarmClient

    made: list[tuple[Any, Any]] = []

    def make(**what: Any) -> Any:
        context = Context()
        rclpy.init(context=context, domain_id=domain_id)
        client = FlexarmClient('test_client', context=context)
        made.append((client, context))
        client.wait_until_ready(timeout=30.0, **what)
        return client

    yield make
    for client, context in made:
        client.destroy_node()
        rclpy.try_shutdown(context=context)
