"""Node-level: the bridge + fake controller in place of the simulator node.

A TCP relay (:class:`~link_proxy.LinkProxy`) sits between the bridge and the
fake controller, so the link can be cut and garbage injected. The tests of :class:`TestLink`
share one such link (started once, stopped when the class ends: the other tests use its ports
and its ROS domain); each reads only the bridge's log lines, wire frames and connections of
its own run, and starts from wherever the arm was left.
"""
import socket
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from flexarm_bridge import controller_protocol as proto
from flexarm_bringup.launcher import stop_all
from flexarm_core import liveness, topics
from flexarm_core.ros.node_main import Spin
from flexarm_test_support.link_proxy import TO_CONTROLLER, LinkProxy

pytestmark = [pytest.mark.node, pytest.mark.duration(65)]


def settle(condition: Callable[[], object], timeout: float, what: str) -> None:
    """conftest's ``wait_for``, for a fixture that outlives a test."""
    deadline = time.monotonic() + liveness.limit(timeout)
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f'timed out waiting for {what}')
        time.sleep(0.02)


def log_since(path: Path) -> Callable[[], str]:
    """What the log ``path`` gains from now on (a shared node's log holds earlier tests')."""
    start = path.stat().st_size
    return lambda: path.read_bytes()[start:].decode(errors='replace')


@pytest.fixture(scope='class')
def link(module_launch, domain_id):
    """Fake controller -> relay -> bridge, and an rclpy node (spun in a thread) that hears
    the joint states and publishes commands, for the tests of a class. Where the joint states
    and the JOINT_COMMAND frames that reach the wire go: ``to['heard']``, ``to['commands']``.
    """
    controller_port, proxy_port = 47000 + 2 * domain_id, 47001 + 2 * domain_id
    nodes = [module_launch('flexarm_fake_controller', robot='bridge', port=controller_port,
                           real_time_factor=2.0, heartbeat_timeout=1.0, clock_source='own')]
    to: dict[str, Any] = {'heard': {'n': 0}, 'commands': []}

    def on_frame(direction: str, _: float, frame: proto.Frame) -> None:
        if direction == TO_CONTROLLER and frame.type == proto.JOINT_COMMAND:
            to['commands'].append(frame.fields['positions'])

    def on_joints(msg: JointState) -> None:
        heard = to['heard']
        heard['js'], heard['n'] = (time.monotonic(), msg), heard['n'] + 1

    proxy = context = node = thread = None
    try:
        settle(lambda: 'controller protocol v' in nodes[0].log_path.read_text(), 30.0,
               'the fake controller to listen')
        proxy = LinkProxy(proxy_port, controller_port, on_frame)
        nodes.append(module_launch('flexarm_bridge', robot='bridge', port=proxy_port,
                                   use_sim_time=False))
        context = Context()
        rclpy.init(context=context, domain_id=domain_id)
        node = rclpy.create_node('test_client', context=context)
        node.create_subscription(JointState, topics.JOINT_STATES, on_joints, 10)
        command = node.create_publisher(Float64MultiArray, topics.JOINT_COMMANDS, 10)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        thread = Spin(executor, lambda: None)
        yield proxy, nodes[1], command, to
    finally:
        stopped = thread is None or thread.stop(5.0)   # the spin ends before the node goes
        if thread is not None:
            executor.shutdown(timeout_sec=2.0)
        if node is not None:
            node.destroy_node()
        if context is not None:
            rclpy.try_shutdown(context=context)
        if proxy is not None:
            proxy.close()
        codes = stop_all(nodes, timeout=5.0)     # before the module's other tests start
        running = [name for name, code in codes.items() if code is None]
        assert not running, f'node(s) {running} could not be stopped and reaped'
        assert stopped, "the test node's executor did not stop"


@pytest.fixture
def bridged(link, wait_for):
    """The link, the joint states heard, the bridge's log and the JOINT_COMMAND frames on the
    wire, all from the test's start."""
    proxy, bridge, command, to = link
    log = log_since(bridge.log_path)
    to['heard'] = heard = {'n': 0}
    wait_for(lambda: 'js' in heard and command.get_subscription_count(), 30.0,
             'joint states through the bridge')
    to['commands'] = commands = []
    return proxy, heard, command, log, commands


def joints(heard) -> np.ndarray:
    return np.array(heard['js'][1].position)


def let_pass(heard, wait_for, states: int = 100) -> None:
    """Wait until ``states`` more joint states arrived (1 s of the controller's time at
    100 Hz): time for anything in flight to show, counted in the controller's ticks."""
    until = heard['n'] + states
    wait_for(lambda: heard['n'] >= until, 30.0, f'{states} more joint states')


class TestLink:
    """Tests of one link (:func:`link`)."""

    def test_commands_flow_limits_hold_and_garbage_is_survived(self, bridged, wait_for):
        proxy, heard, command, log, commands = bridged
        links = proxy.connections
        target = [0.1, 0.62, -0.45, -0.5]
        command.publish(Float64MultiArray(data=target))
        wait_for(lambda: np.allclose(joints(heard), target, atol=1e-9), 30.0, 'the move')
        command.publish(Float64MultiArray(data=[0.1, 0.95, -0.45, -0.5]))  # joint2 > 0.8 m
        wait_for(lambda: 'rejected, not forwarded' in log(), 10.0,
                 'the bridge to reject the command')
        proxy.inject(b'\x00\x01garbage\xfaW\x01\x02' + bytes(range(256)))
        wait_for(lambda: 'rejected from the controller' in log(), 10.0,
                 'the controller to refuse the garbage')
        let_pass(heard, wait_for)                                       # still streaming
        np.testing.assert_allclose(joints(heard), target, atol=1e-9)
        assert commands == [target]                                     # never on the wire
        assert proxy.connections == links                               # link survived

    def test_link_cut_mid_move_recovers_only_on_a_fresh_command(self, bridged, wait_for):
        proxy, heard, command, log, commands = bridged
        start = joints(heard)
        far = [0.6, 0.6, -0.5, -0.5]                     # 3.4 s of sim motion from home
        command.publish(Float64MultiArray(data=far))
        wait_for(lambda: abs(joints(heard)[0] - start[0]) > 0.05, 10.0, 'motion')
        links = proxy.connections
        proxy.cut()
        wait_for(lambda: 'link to the controller lost' in log(), 10.0,
                 'the bridge to report the link loss')
        wait_for(lambda: proxy.connections > links, 15.0, 'the bridge to reconnect')
        let_pass(heard, wait_for)                                       # joint states again
        held = joints(heard)
        assert 0.05 < held[0] - start[0] < far[0] - start[0] - 0.05      # stopped midway
        let_pass(heard, wait_for)
        np.testing.assert_allclose(joints(heard), held, atol=1e-9)      # nothing replayed
        assert commands == [far]                                        # (not even sent)
        command.publish(Float64MultiArray(data=far))                    # fresh command
        wait_for(lambda: np.allclose(joints(heard), far, atol=1e-9), 30.0, 'the fresh move')


def test_unreachable_controller_is_reported_and_retried(launch, ros_node, domain_id, wait_for):
    port = 47000 + 2 * domain_id
    health: dict[str, DiagnosticStatus] = {}
    ros_node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, lambda m: health.update(
        {s.name: s for s in m.status}), 10)
    bridge = launch('flexarm_bridge', robot='bridge', port=port, use_sim_time=False,
                    retry_max=0.5)
    wait_for(lambda: 'unreachable' in bridge.log_path.read_text(), 30.0, 'the error')
    link, pc = 'flexarm_bridge: controller link', 'flexarm_fake_controller: link'

    def level(name: str) -> bytes | None:
        return health[name].level if name in health else None

    wait_for(lambda: level(link) == DiagnosticStatus.ERROR, 10.0, 'link ERROR on /diagnostics')
    assert 'unreachable' in health[link].message
    assert health[link].hardware_id == f'127.0.0.1:{port}'
    heard = []
    ros_node.create_subscription(JointState, topics.JOINT_STATES, heard.append, 10)
    launch('flexarm_fake_controller', robot='bridge', port=port)
    wait_for(lambda: heard, 30.0, 'joint states once the controller is up')
    wait_for(lambda: level(link) == DiagnosticStatus.OK and level(pc) == DiagnosticStatus.OK,
             10.0, 'both ends of the link OK on /diagnostics')


def test_a_controller_that_drops_every_connection_is_not_hammered(launch, domain_id,
                                                                   wait_for):
    """No HELLO is ever accepted, so the backoff keeps growing: 0.2, 0.4, 0.8, 1.6 s..."""
    accepted: list[float] = []
    server = socket.create_server(('127.0.0.1', 47000 + 2 * domain_id))
    server.settimeout(0.1)

    def serve() -> None:
        while server.fileno() >= 0:
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            accepted.append(time.monotonic())
            conn.close()

    threading.Thread(target=serve, daemon=True).start()
    try:
        launch('flexarm_bridge', robot='bridge', port=47000 + 2 * domain_id,
               use_sim_time=False, retry_min=0.2, retry_max=5.0)
        wait_for(lambda: accepted, 30.0, 'the bridge to connect')
        time.sleep(3.5)
    finally:
        server.close()
    in_window = [t for t in accepted if t - accepted[0] < 3.5]
    assert 3 <= len(in_window) <= 6, np.diff(in_window)
