"""A client leaves no shared memory behind: the ports it listened on, which a peer killed while
it ran had opened to send to it, go when its context shuts down (Fast DDS keeps a port while a
dead process still counts as its user)."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest
import rclpy
from rclpy.context import Context

from flexarm_control.ros.client import FlexarmClient
from flexarm_core.dds_shm import listened_ports, owned_shm

pytestmark = [pytest.mark.node]
TIMEOUT = 30.0    # [s] a bound for the peer's discovery; it takes well under a second

PEER = textwrap.dedent('''
    import sys, time
    import rclpy
    rclpy.init(domain_id=int(sys.argv[1]))
    node = rclpy.create_node('flexarm_peer')
    node.create_publisher(__import__('std_msgs.msg').msg.Empty, 'peer_chatter', 10)
    print('ready', flush=True)
    while True:
        rclpy.spin_once(node, timeout_sec=0.1)
''')


def test_the_ports_a_killed_peer_opened_go_with_the_client(domain_id, wait_for):
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    client = FlexarmClient('flexarm_port_probe', context=context)
    ports = [p for p in listened_ports(owned_shm(os.getpid()))
             if p.name.startswith('fastrtps_port') and not p.name.endswith(('_el', '_mutex'))]
    peer = subprocess.Popen([sys.executable, '-c', PEER, str(domain_id)],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert peer.stdout.readline().strip() == 'ready'
        wait_for(lambda: set(ports) & set(owned_shm(peer.pid)), TIMEOUT,
                 "the peer to open the client's ports")
    finally:
        peer.kill()
        peer.wait(TIMEOUT)
        peer.stdout.close()
    assert all(p.exists() for p in ports)
    client.destroy_node()
    context.try_shutdown()
    assert [p.name for p in ports if p.exists()] == []
