"""Fault injection on the authenticated controller link: what a peer without the site key, armed
with recordings of genuine connections, can do to the fake controller and to the bridge.

The attacks speak raw bytes (:mod:`link_attacks`: frames cut by their headers, not decoded), so
they mean the same whatever the protocol version on the wire. Every wait is on an event, bounded
by a liveness limit.
"""
import threading

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState

from flexarm_bridge import controller_protocol as proto
from flexarm_bridge.link_auth import load_key, make_key
from flexarm_core import liveness, topics
from flexarm_test_support.link_attacks import (
    KeylessController,
    Recording,
    exchange,
    first_frame,
    record_session,
    replay_attacks,
    split_frames,
)
from flexarm_test_support.link_proxy import TO_CONTROLLER, TO_PC, LinkProxy

pytestmark = [pytest.mark.node, pytest.mark.duration(50)]

TIMEOUT = 1.0                       # [s] heartbeat timeout of both ends (config/bridge.yaml)
LINK = 'flexarm_bridge: controller link'


@pytest.fixture
def keyed(launch, domain_id, tmp_path, wait_for):
    """A fake controller with a site key: (its port, the key file, a free second port, node)."""
    port = 47000 + 2 * domain_id
    key = str(make_key(tmp_path / 'site.key'))
    controller = launch('flexarm_fake_controller', robot='bridge', port=port, link_key_file=key,
                        heartbeat_timeout=TIMEOUT, real_time_factor=2.0,
                        clock_source='own')
    wait_for(lambda: 'controller protocol v' in controller.log_path.read_text(), 30.0,
             'the fake controller to listen')
    return port, key, port + 1, controller


def bridge(launch, port: int, key: str):
    return launch('flexarm_bridge', robot='bridge', port=port, link_key_file=key,
                  use_sim_time=False, heartbeat_timeout=TIMEOUT)


def joint_states(ros_node) -> list:
    heard: list = []
    ros_node.create_subscription(JointState, topics.JOINT_STATES, heard.append, 10)
    return heard


def link_levels(ros_node) -> list[tuple[bytes, str]]:
    """(level, message) of every report of the bridge's controller link on /diagnostics."""
    seen: list[tuple[bytes, str]] = []
    ros_node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, lambda msg: seen.extend(
        (s.level, s.message) for s in msg.status if s.name == LINK), 10)
    return seen


def test_a_keyless_peer_replaying_the_hello_is_dropped_and_the_pc_gets_the_link(
        keyed, launch, ros_node, wait_for):
    """The controller's own HELLO sent back every 0.3 s: no sign of life, so the peer is
    disconnected within the heartbeat timeout, and the bridge waiting meanwhile links."""
    port, key, _, controller = keyed
    stop, outcome = threading.Event(), {}
    attacker = threading.Thread(target=lambda: outcome.update(replayer=exchange(
        port, 'HELLO reflected', [], liveness.limit(60.0), repeat=True, reflect=True,
        stop=stop)), daemon=True)
    attacker.start()
    try:
        wait_for(lambda: 'PC connected' in controller.log_path.read_text(), 10.0,
                 'the replayer to take the slot')
        heard = joint_states(ros_node)
        bridge(launch, port, key)
        wait_for(lambda: 'replayer' in outcome, TIMEOUT + 1.0,
                 'the controller to drop the replaying peer')
        replayer = outcome['replayer']
        assert replayer.closed and not replayer.accepted, replayer
        assert proto.HELLO in replayer.received
        assert replayer.held_s < liveness.limit(TIMEOUT + 0.5)
        wait_for(lambda: heard, 15.0, 'joint states through the bridge (the PC has the link)')
    finally:
        stop.set()
        attacker.join(timeout=liveness.limit(5.0))
    assert 'not authenticated within' in controller.log_path.read_text()


def test_a_handshake_recorded_from_an_earlier_connection_is_refused(keyed, launch, wait_for):
    """An eavesdropper's recording of the bridge's session: its AUTH (and the rest it sent)
    replayed, and the controller's own frames of it reflected, on new connections: none gets
    a joint state or any other sign of an accepted handshake."""
    port, key, proxy_port, controller = keyed
    proxy = LinkProxy(proxy_port, port, record=True)
    try:
        bridge(launch, proxy_port, key)
        wait_for(lambda: proxy.recorded and proto.JOINT_STATE in
                 [f[3] for f in split_frames(bytes(proxy.recorded[0][TO_PC]))], 30.0,
                 'a session of the bridge through the relay')
    finally:
        proxy.close()                             # the bridge cannot come back
    proxy.cut()
    wait_for(lambda: 'link to the PC lost' in controller.log_path.read_text(), 10.0,
             'the controller to see the bridge go')
    tape = proxy.recorded[0]
    recording = Recording(bytes(tape[TO_CONTROLLER]), bytes(tape[TO_PC]))
    assert proto.AUTH in [f[3] for f in split_frames(recording.to_controller)]
    report = replay_attacks(port, recording, seconds=liveness.limit(TIMEOUT + 2.0))
    assert report.replay_accepted == 0, report.exchanges
    for attempt in report.exchanges:
        assert not attempt.busy and proto.JOINT_STATE not in attempt.received, attempt
        assert attempt.closed and attempt.held_s < liveness.limit(TIMEOUT + 0.5), attempt
    log = controller.log_path.read_text()
    assert 'does not match' in log and 'reflected' in log
    assert record_session(port, load_key(key)).to_pc        # the genuine key still works


def test_frames_reflected_to_the_bridge_are_refused(keyed, launch, ros_node, wait_for):
    """A keyless controller sends a recorded HELLO once and reflects every frame the bridge
    sends (its AUTH): the bridge never reports the link up and drops each connection within
    the heartbeat timeout."""
    port, key, fake_port, _ = keyed
    reports = link_levels(ros_node)
    impostor = KeylessController(fake_port, first_frame(port), reflect=True)
    try:
        node = bridge(launch, fake_port, key)
        wait_for(lambda: len([c for c in impostor.connections if c['closed']]) >= 2
                 and len(reports) >= 2, 30.0, 'two connections of the bridge dropped')
    finally:
        impostor.close()
    for connection in impostor.connections[:2]:
        assert proto.AUTH in connection['received'], connection
        assert connection['closed'] - connection['opened'] < liveness.limit(TIMEOUT + 0.5)
    assert all(level != DiagnosticStatus.OK for level, _ in reports), reports
    assert 'reflected' in node.log_path.read_text()


def test_a_keyless_controller_replaying_a_hello_never_gets_the_bridge_linked(
        keyed, launch, ros_node, wait_for):
    """A recorded HELLO replayed every 0.3 s: the bridge answers, gets no proof, counts no
    sign of life, and keeps reporting the link down; no joint state is published."""
    port, key, fake_port, _ = keyed
    reports, heard = link_levels(ros_node), joint_states(ros_node)
    impostor = KeylessController(fake_port, first_frame(port), repeat=True)
    try:
        node = bridge(launch, fake_port, key)
        wait_for(lambda: len([c for c in impostor.connections if c['closed']]) >= 3
                 and len(reports) >= 3, 30.0, 'three connections of the bridge dropped')
    finally:
        impostor.close()
    for connection in impostor.connections[:3]:
        assert connection['closed'] - connection['opened'] < liveness.limit(TIMEOUT + 0.5)
    assert all(level != DiagnosticStatus.OK for level, _ in reports), reports
    assert heard == []
    log = node.log_path.read_text()
    assert 'no authenticated session within' in log and 'linked:' not in log


def test_the_keyed_bridge_reads_a_busy_refusal(keyed, launch, ros_node, wait_for):
    """While an authenticated PC holds the link the controller refuses the bridge with ERROR
    code 5 before any session: the bridge logs and reports it (unauthenticated), and links
    once the slot is free."""
    port, key, _, _ = keyed
    stop = threading.Event()
    holder = threading.Thread(target=record_session, args=(port, load_key(key), None, stop),
                              daemon=True)
    holder.start()
    try:
        reports, heard = link_levels(ros_node), joint_states(ros_node)
        node = bridge(launch, port, key)
        wait_for(lambda: any('another PC is connected' in m for _, m in reports), 30.0,
                 'the refusal on /diagnostics')
        assert 'controller error 5 (unauthenticated' in node.log_path.read_text()
    finally:
        stop.set()
        holder.join(timeout=liveness.limit(5.0))
    wait_for(lambda: heard, 30.0, 'joint states once the slot is free')
