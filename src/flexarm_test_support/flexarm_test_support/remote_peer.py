"""A peer on another host tries to command the arm: what it sees of the graph, and whether the
arm moves.

The other host is a Linux network namespace joined to this one by a veth pair (root only), with
its own /dev/shm, as a computer on the same network has: nothing of this machine's shared
memory, only its network. The intruder uses plain ROS defaults (no flexarm profile, default
transports and discovery range) and names this host in ``ROS_STATIC_PEERS``; it lists the nodes
it discovers and publishes joint commands. Whether the arm moved is read on this host, from
``joint_states``, by an observer process confined like a flexarm client.

Used by tests/test_faults_network.py and, with tests/ on ``sys.path``, by the benchmarks.
"""
from __future__ import annotations

import ipaddress
import json
import os
import queue
import shutil
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import pytest

from flexarm_bringup.launcher import ros_env
from flexarm_core import liveness

MOVED = 1e-4          # [rad, m] a joint that changed by more than this moved
# [s] the peer tries: two of Fast DDS's 3 s participant announcements (a peer of an open graph
# was in after 0.5-2.5 s)
ATTEMPT = 6.0
SUBNETS = ipaddress.ip_network('10.213.0.0/16')   # the hosts' /24s are taken from here
# Variables that would make the intruder anything but a plain ROS process of another host.
NOT_PLAIN = ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_LOCALHOST_ONLY', 'ROS_STATIC_PEERS',
             'FASTRTPS_DEFAULT_PROFILES_FILE', 'SKIP_DEFAULT_XML_FILE',
             'FASTDDS_BUILTIN_TRANSPORTS', '_ROS_WHEELS_BOOTSTRAP_COMPLETE')

INTRUDER = '''
import json, sys, time
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

duration, namespace, moved = float(sys.argv[1]), sys.argv[2], float(sys.argv[3])
blind = [0.0, 0.6, -0.5, -0.5]      # the simulator's start, for an arm it cannot see
context = Context()
rclpy.init(context=context)
node = rclpy.create_node('intruder', namespace=namespace, context=context)
joints = []
node.create_subscription(JointState, 'joint_states',
                         lambda msg: joints.append(list(msg.position)), 10)
publisher = node.create_publisher(Float64MultiArray, 'forward_position_controller/commands', 10)
executor = SingleThreadedExecutor(context=context)
executor.add_node(node)
seen, published, next_command, found = set(), 0, 0.0, None
start = time.monotonic()
deadline = start + duration
while time.monotonic() < deadline:
    executor.spin_once(timeout_sec=0.05)
    seen |= {ns.rstrip('/') + '/' + name for name, ns in node.get_node_names_and_namespaces()
             if name not in ('intruder', '_NODE_NAME_UNKNOWN_')}
    if seen and found is None:
        found = time.monotonic() - start
    if seen and joints and max(abs(a - b) for a, b in zip(joints[-1], joints[0])) > moved:
        break                   # it found the graph and moved the arm: nothing left to prove
    if time.monotonic() >= next_command:
        q = joints[0] if joints else blind
        publisher.publish(Float64MultiArray(data=[q[0] + (0.05 if q[0] <= 0 else -0.05),
                                                  *q[1:]]))
        published, next_command = published + 1, time.monotonic() + 0.1
print(json.dumps({'nodes_seen': sorted(seen), 'seen_after': found,
                  'commands_published': published, 'joint_states_seen': len(joints)}))
executor.shutdown()
node.destroy_node()
rclpy.try_shutdown(context=context)
'''

OBSERVER = '''
import json, sys, threading
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import JointState

namespace, moved = sys.argv[1], float(sys.argv[2])
context = Context()
rclpy.init(context=context)
node = rclpy.create_node('remote_peer_observer', namespace=namespace, context=context)
state = {'first': None, 'change': 0.0}
lock = threading.Lock()

def on_joints(msg):
    q = list(msg.position)
    with lock:
        if state['first'] is None:
            state['first'] = q
            print(json.dumps({'ready': q}), flush=True)
            return
        change = max(abs(a - b) for a, b in zip(q, state['first']))
        if change > moved >= state['change']:
            print(json.dumps({'moved': change}), flush=True)
        state['change'] = max(state['change'], change)

node.create_subscription(JointState, 'joint_states', on_joints, 10)
executor = SingleThreadedExecutor(context=context)
executor.add_node(node)
threading.Thread(target=executor.spin, daemon=True).start()
sys.stdin.read()                       # until the caller is done
with lock:
    print(json.dumps({'max_joint_change': state['change']}), flush=True)
executor.shutdown()
node.destroy_node()
rclpy.try_shutdown(context=context)
'''


class Unavailable(RuntimeError):
    """This machine cannot make network namespaces (not root, no iproute2, not allowed)."""


def unavailable() -> str | None:
    """Why no other host can be made here (network namespaces need root and iproute2), or
    None."""
    if shutil.which('ip') is None:
        return 'iproute2 (`ip`) is not installed'
    if os.geteuid() != 0:
        return 'network namespaces need root'
    return None


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    done = subprocess.run(['ip', *args], capture_output=True, text=True, timeout=10)
    if check and done.returncode != 0:
        raise RuntimeError(f'ip {" ".join(args)}: {done.stderr.strip()}')
    return done


def _free_subnet() -> ipaddress.IPv4Network:
    """A /24 of :data:`SUBNETS` that no interface of this namespace uses."""
    used = {ipaddress.ip_interface(f'{a["local"]}/{a["prefixlen"]}').network
            for link in json.loads(_ip('-j', 'addr', 'show').stdout)
            for a in link.get('addr_info', ()) if a.get('family') == 'inet'}
    for subnet in SUBNETS.subnets(new_prefix=24):
        if not any(subnet.overlaps(u) for u in used):
            return subnet
    raise RuntimeError(f'no free /24 left in {SUBNETS}')


class RemoteHost:
    """Another host on this machine's network: a namespace ``name`` whose veth end has
    ``remote_address``; this host's end has ``address`` (what the peer names)."""

    _made = 0

    def __init__(self) -> None:
        RemoteHost._made += 1
        tag = f'{os.getpid()}x{RemoteHost._made}'
        self.name, self._link, self._peer_link = f'fxpeer{tag}', f'fxh{tag}', f'fxp{tag}'
        self.address = self.remote_address = ''

    def create(self) -> None:
        """Make the namespace, the veth pair and their addresses; :class:`Unavailable` if
        no namespace can be made here, RuntimeError if ``ip`` refuses the rest (what was made
        is removed)."""
        reason = unavailable()
        if reason is None:
            made = _ip('netns', 'add', self.name, check=False)
            if made.returncode != 0:
                reason = made.stderr.strip() or f'ip netns add exited {made.returncode}'
        if reason is not None:
            raise Unavailable(f'cannot make a network namespace: {reason}')
        try:
            subnet = _free_subnet()
            local, remote = (f'{host}/{subnet.prefixlen}' for host in list(subnet.hosts())[:2])
            _ip('link', 'add', self._link, 'type', 'veth', 'peer', 'name', self._peer_link)
            _ip('link', 'set', self._peer_link, 'netns', self.name)
            _ip('addr', 'add', local, 'dev', self._link)
            _ip('link', 'set', self._link, 'up')
            for command in (('addr', 'add', remote, 'dev', self._peer_link),
                            ('link', 'set', 'lo', 'up'), ('link', 'set', self._peer_link, 'up'),
                            ('route', 'add', 'default', 'via', local.split('/')[0])):
                _ip('-n', self.name, *command)
        except BaseException:
            self.remove()
            raise
        self.address, self.remote_address = local.split('/')[0], remote.split('/')[0]

    def remove(self) -> None:
        """Delete the namespace and the veth pair (either end takes the other along)."""
        _ip('netns', 'delete', self.name, check=False)
        _ip('link', 'delete', self._link, check=False)

    def __enter__(self) -> RemoteHost:
        self.create()
        return self

    def __exit__(self, *exc: object) -> None:
        self.remove()

    @classmethod
    @contextmanager
    def made(cls) -> Iterator[RemoteHost]:
        """A host for the block, removed after it; the test is skipped on a machine that
        cannot make one."""
        host = cls()
        try:
            host.create()
        except Unavailable as exc:
            pytest.skip(str(exc))
        try:
            yield host
        finally:
            host.remove()

    def python(self, code: str, args: list[str], env: dict[str, str], timeout: float
               ) -> subprocess.CompletedProcess[str]:
        """Run ``python -c code args`` in the namespace, on a /dev/shm of its own (``ip netns
        exec`` gives it a mount namespace of its own, so the mount stays in there)."""
        return subprocess.run(
            ['ip', 'netns', 'exec', self.name, 'sh', '-c',
             'mount -t tmpfs -o size=256m flexarm-peer-shm /dev/shm && exec "$0" "$@"',
             sys.executable, '-c', code, *args],
            env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=timeout)


def intruder_env(domain_id: int, peer: str, log_dir: str) -> dict[str, str]:
    """A plain ROS environment of another host: the domain, this host as static peer."""
    env = {k: v for k, v in os.environ.items() if k not in NOT_PLAIN}
    return env | {'ROS_DOMAIN_ID': str(domain_id), 'ROS_STATIC_PEERS': peer,
                  'ROS_LOG_DIR': log_dir, 'PYTHONUNBUFFERED': '1'}


class _Lines:
    """The JSON lines a process prints, read in a thread: wait for one without polling."""

    def __init__(self, stream: IO[str]) -> None:
        self._queue: queue.Queue[dict[str, Any] | None] = queue.Queue()
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            if line.startswith('{'):
                self._queue.put(json.loads(line))
        self._queue.put(None)

    def wait(self, key: str, timeout: float) -> dict[str, Any] | None:
        """The next line holding ``key`` within ``timeout`` s, or None (also at the end)."""
        try:
            while (line := self._queue.get(timeout=timeout)) is not None:
                if key in line:
                    return line
        except queue.Empty:
            pass
        return None


@contextmanager
def _observer(domain_id: int, namespace: str, log_dir: str) -> Iterator[_Lines]:
    """The observer of ``joint_states`` on this host, confined like any flexarm client."""
    process = subprocess.Popen(
        [sys.executable, '-c', OBSERVER, namespace, str(MOVED)],
        env=ros_env(domain_id, Path(log_dir), discovery='LOCALHOST'),
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    assert process.stdin is not None and process.stdout is not None
    try:
        yield _Lines(process.stdout)
    finally:
        process.stdin.close()
        try:
            process.wait(timeout=liveness.limit(10.0))
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def remote_attack(domain_id: int, namespace: str = '', attempt: float = ATTEMPT,
                  host: RemoteHost | None = None) -> dict[str, Any]:
    """Let a peer on another host (``host``, or one made for the call) try for ``attempt``
    wall seconds (scaled, :func:`flexarm_core.liveness.limit`) to command the arm of the
    graph in ``domain_id`` (under ``/namespace``), which must be publishing ``joint_states``.

    Returns ``nodes_seen`` (the nodes the peer discovered; ``seen_after`` [s] the first, or
    None), ``moved`` (the arm moved, seen on this host), ``max_joint_change`` [rad, m],
    ``commands_published`` and ``joint_states_seen`` (by the peer, which stops once it saw the
    arm move). RuntimeError if this host sees no ``joint_states`` or the peer's process fails.
    """
    if host is None:
        with RemoteHost() as made:
            return remote_attack(domain_id, namespace, attempt, made)
    namespace = f'/{namespace.strip("/")}' if namespace.strip('/') else ''
    with tempfile.TemporaryDirectory(prefix='flexarm-remote-peer-') as logs, \
            _observer(domain_id, namespace, logs) as observed:
        if observed.wait('ready', liveness.limit(20.0)) is None:
            raise RuntimeError(f'no joint_states in ROS domain {domain_id}{namespace} on '
                               'this host: is the graph running?')
        tried = liveness.limit(attempt)
        done = host.python(INTRUDER, [str(tried), namespace, str(MOVED)],
                           intruder_env(domain_id, host.address, logs),
                           timeout=tried + liveness.limit(30.0))
        if done.returncode != 0:
            raise RuntimeError(f'the remote peer failed ({done.returncode}): '
                               f'{done.stderr.strip()[-2000:]}')
        result = json.loads(done.stdout.strip().splitlines()[-1])
        moved = observed.wait('moved', liveness.limit(1.0)) is not None
    final = observed.wait('max_joint_change', liveness.limit(5.0)) or {}
    return result | {'moved': moved, 'max_joint_change': final.get('max_joint_change')}
