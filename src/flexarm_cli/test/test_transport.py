"""Which Fast DDS transports a process gets: confined to this machine unless widened."""
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from flexarm_bringup.launcher import load_graph, load_optional, ros_env
from flexarm_core import liveness
from flexarm_core.transport import (
    PEERS_ENV,
    PROFILES_ENV,
    RANGE_ENV,
    SKIP_CWD_ENV,
    apply,
    exposed,
    localhost_profile,
    profile_problem,
    transport_env,
    warning,
)

FASTDDS = '{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}'
ARMS = 4            # benchmarks/multi_arm.py's most, in one domain
RMW_REACH = 32      # rmw_fastrtps's maxInitialPeersRange for LOCALHOST discovery
# Participants, one node each, in one process; prints, as JSON, the participants each misses.
MESH = """
import json, sys, time
import rclpy
from rclpy.context import Context
count, deadline = int(sys.argv[1]), time.monotonic() + float(sys.argv[2])
nodes = []
for i in range(count):
    context = Context()
    rclpy.init(context=context)
    nodes.append(rclpy.create_node(f'peer{i}', context=context))
names = {n.get_name() for n in nodes}
while True:
    missed = {n.get_name(): sorted(names - {m for m, _ in n.get_node_names_and_namespaces()})
              for n in nodes}
    if not any(missed.values()) or time.monotonic() > deadline:
        break
    time.sleep(0.2)
print(json.dumps({k: v for k, v in missed.items() if v}))
for node in nodes:
    node.destroy_node()
    rclpy.try_shutdown(context=node.context)
"""


def loopback_reach() -> int:
    """maxInitialPeersRange of the localhost profile's UDPv4 transport (Fast DDS's 4 unset)."""
    root = ET.parse(localhost_profile()).getroot()
    return max(int(d.findtext(f'{FASTDDS}maxInitialPeersRange') or 4)
               for d in root.iterfind(f'.//{FASTDDS}transport_descriptor')
               if d.findtext(f'{FASTDDS}type') == 'UDPv4')


def site_participants() -> int:
    """Participants of ARMS arms in one domain: each graph's nodes with every optional one,
    its supervisor's probe and a client, and multi_arm.py's monitor."""
    return ARMS * (len(load_graph('sim')) + len(load_optional('sim')) + 2) + 1


def test_the_localhost_profile_replaces_the_builtin_transports_by_shm_and_loopback():
    root = ET.parse(localhost_profile()).getroot()
    participant = root.find(f'.//{FASTDDS}participant')
    assert participant is not None and participant.get('is_default_profile') == 'true'
    rtps = participant.find(f'{FASTDDS}rtps')
    assert rtps.findtext(f'{FASTDDS}useBuiltinTransports') == 'false'
    used = [t.text for t in rtps.iterfind(f'{FASTDDS}userTransports/{FASTDDS}transport_id')]
    descriptors = {d.findtext(f'{FASTDDS}transport_id'): d
                   for d in root.iterfind(f'.//{FASTDDS}transport_descriptor')}
    assert sorted(descriptors[t].findtext(f'{FASTDDS}type') for t in used) == ['SHM', 'UDPv4']
    for t in used:
        if descriptors[t].findtext(f'{FASTDDS}type') == 'UDPv4':
            allowed = [a.text for a in descriptors[t].iter(f'{FASTDDS}address')]
            assert allowed == ['127.0.0.1']


def test_discovery_on_this_machine_reaches_every_participant_of_four_arms():
    """A participant id beyond the reach is found by no other beyond it, nor by a client
    without LOCALHOST discovery: rmw_fastrtps's 32 fell one short of multi_arm.py's 4 arms.
    Fast DDS announces to the widest reach of a participant's UDPv4 transports."""
    assert max(loopback_reach(), RMW_REACH) >= site_participants()


@pytest.mark.node
def test_participants_beyond_rmws_reach_find_each_other(domain_id: int):
    """More participants than rmw_fastrtps's own reach, with the nodes' environment: each one
    finds every other (with rmw's 32, the 33rd and 34th never find each other)."""
    count = RMW_REACH + 2
    done = subprocess.run([sys.executable, '-c', MESH, str(count), str(liveness.limit(10.0))],
                          env=ros_env(domain_id), capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert json.loads(done.stdout.splitlines()[-1]) == {}


@pytest.mark.parametrize('env, expected', [
    ({RANGE_ENV: 'LOCALHOST'}, False),
    ({RANGE_ENV: 'localhost '}, False),
    ({RANGE_ENV: 'OFF'}, False),
    ({RANGE_ENV: 'SUBNET'}, True),
    ({RANGE_ENV: 'SYSTEM_DEFAULT'}, True),
    ({}, True),                                          # rcl's default range is SUBNET
    ({RANGE_ENV: 'LOCALHOST', PEERS_ENV: '10.0.0.2'}, True),
    ({RANGE_ENV: 'LOCALHOST', PEERS_ENV: ' '}, False),
])
def test_exposed_means_a_range_beyond_localhost_or_static_peers(env, expected):
    assert exposed(env) is expected


def test_localhost_gets_the_profile_and_no_profile_of_the_working_directory():
    env = transport_env({RANGE_ENV: 'LOCALHOST', 'PATH': '/bin'})
    assert env == {RANGE_ENV: 'LOCALHOST', 'PATH': '/bin', PROFILES_ENV: localhost_profile(),
                   SKIP_CWD_ENV: '1'}
    assert Path(env[PROFILES_ENV]).is_file()


def test_a_widened_range_drops_flexarms_profile_but_keeps_the_users():
    confined = transport_env({RANGE_ENV: 'LOCALHOST'})
    assert transport_env(confined | {RANGE_ENV: 'SUBNET'}) == {RANGE_ENV: 'SUBNET'}
    assert transport_env(confined | {PEERS_ENV: '10.0.0.2'}) == {
        RANGE_ENV: 'LOCALHOST', PEERS_ENV: '10.0.0.2'}
    users = {RANGE_ENV: 'LOCALHOST', PROFILES_ENV: '/site/dds.xml'}
    assert transport_env(users) == users
    assert transport_env(users | {RANGE_ENV: 'SUBNET'}) == users | {RANGE_ENV: 'SUBNET'}


def test_apply_changes_the_environment_in_place():
    environ = {RANGE_ENV: 'LOCALHOST', 'PATH': '/bin'}
    apply(environ)
    assert environ[PROFILES_ENV] == localhost_profile() and environ[SKIP_CWD_ENV] == '1'
    environ[RANGE_ENV] = 'SUBNET'
    apply(environ)
    assert environ == {RANGE_ENV: 'SUBNET', 'PATH': '/bin'}


def test_warning_says_anyone_on_the_network_can_command_the_arm():
    assert warning(transport_env({RANGE_ENV: 'LOCALHOST'})) is None
    subnet = warning({RANGE_ENV: 'SUBNET'})
    assert subnet.startswith('WARNING') and 'discovery range SUBNET' in subnet
    assert 'anyone on that network' in subnet and 'can command the arm' in subnet
    assert 'no DDS-Security' in subnet
    assert f'{PEERS_ENV}=10.0.0.2' in warning({RANGE_ENV: 'LOCALHOST', PEERS_ENV: '10.0.0.2'})
    users = warning({RANGE_ENV: 'LOCALHOST', PROFILES_ENV: '/site/dds.xml'})
    assert '/site/dds.xml' in users and 'decide who can reach the graph' in users


def test_node_environments_follow_their_discovery_range():
    base = {'PATH': '/bin', PROFILES_ENV: localhost_profile(), SKIP_CWD_ENV: '1'}
    assert ros_env(3, base={'PATH': '/bin'})[PROFILES_ENV] == localhost_profile()
    subnet = ros_env(3, base=base, discovery='SUBNET')
    assert PROFILES_ENV not in subnet and SKIP_CWD_ENV not in subnet


def test_the_cli_confines_its_own_process_before_any_command(monkeypatch):
    import flexarm_cli as cli

    for name, value in ((RANGE_ENV, ''), (PROFILES_ENV, ''), (SKIP_CWD_ENV, '0')):
        monkeypatch.setenv(name, value)       # restored after the test
        monkeypatch.delenv(name)
    monkeypatch.delenv(PEERS_ENV, raising=False)
    seen = {}

    def run(args):
        seen.update(os.environ)
        return {}, cli.Exit.OK

    monkeypatch.setattr(cli, '_run', run)
    assert cli.main(['status']) == cli.Exit.OK
    assert seen[RANGE_ENV] == 'LOCALHOST' and seen[PROFILES_ENV] == localhost_profile()


def test_a_profiles_file_fast_dds_would_ignore_is_named_with_its_fault(tmp_path: Path):
    assert profile_problem({}) is None
    assert profile_problem(transport_env({RANGE_ENV: 'LOCALHOST'})) is None
    broken = tmp_path / 'dds.xml'
    broken.write_text('<dds><!-- two -- hyphens --></dds>')     # XML forbids -- in a comment
    problem = profile_problem({PROFILES_ENV: str(broken)})
    assert problem.startswith(f'the Fast DDS profiles file {broken} ({PROFILES_ENV}) cannot be '
                              'used: not well-formed (invalid token): line 1')
    assert problem.endswith('Fast DDS would ignore it and run with its defaults; nothing was '
                            'started')
    assert 'No such file' in profile_problem({PROFILES_ENV: str(tmp_path / 'missing.xml')})
