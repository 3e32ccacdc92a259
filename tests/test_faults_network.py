"""Node level: nobody off this machine moves the arm.

A peer on another host (tests/remote_peer.py: a network namespace behind a veth pair, with its
own /dev/shm) runs plain ROS with this host in ``ROS_STATIC_PEERS`` and publishes joint
commands. By default (discovery LOCALHOST, transports confined to shared memory and loopback)
it sees no node and the arm stays where it is. ``flexarm up --discovery subnet`` opens the
graph on purpose: it says so, and the same peer then sees the simulator and moves the arm,
which shows that the attack reaches a graph open to the network. Skipped where no network
namespace can be made (not root, no iproute2).
"""
from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Iterator

import pytest

from flexarm_core import liveness
from flexarm_test_support.remote_peer import RemoteHost, remote_attack

pytestmark = [pytest.mark.node, pytest.mark.duration(50)]


@pytest.fixture
def remote_host() -> Iterator[RemoteHost]:
    """Another host on this machine's network, removed when the test ends."""
    with RemoteHost.made() as host:
        yield host


def test_a_peer_on_another_host_neither_sees_nor_moves_the_arm(launch, domain_id, remote_host):
    launch('flexarm_sim')
    attack = remote_attack(domain_id, host=remote_host)
    assert attack['nodes_seen'] == [], attack
    assert not attack['moved'], attack


def test_up_with_discovery_subnet_warns_and_lets_that_peer_command_the_arm(
        domain_id, tmp_path, remote_host):
    output = tmp_path / 'up.log'
    with open(output, 'wb') as out:
        up = subprocess.Popen(
            [sys.executable, '-m', 'flexarm_cli', 'up', '--only', 'sim', '--discovery',
             'subnet', '--domain-id', str(domain_id), '--name', 'open', '--timeout', '600'],
            stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT)
    try:
        attack = remote_attack(domain_id, host=remote_host)
    except RuntimeError as exc:                  # no simulator to attack: say why
        pytest.fail(f'{exc}\n`up` said:\n{output.read_text(errors="replace")}')
    finally:
        stopped = _stop(up)
    text = output.read_text(errors='replace')
    assert ('WARNING: the graph is open to the network (discovery range SUBNET): anyone on '
            'that network who joins this ROS domain can command the arm') in text, text
    # The peer reached the graph and moved the arm; it stops at the first sign of motion, which
    # may come before discovery has named every node (one run saw only the supervisor's).
    assert attack['nodes_seen'], attack
    assert attack['moved'], attack
    assert stopped and 'stopped: flexarm_sim (0)' in text, text


def _stop(up: subprocess.Popen[bytes]) -> bool:
    """SIGINT ``up`` (it stops its nodes); whether it ended in time (else killed)."""
    up.send_signal(signal.SIGINT)
    try:
        up.wait(timeout=liveness.limit(15.0))
        return True
    except subprocess.TimeoutExpired:
        up.kill()
        up.wait()
        return False
