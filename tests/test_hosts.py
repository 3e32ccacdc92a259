"""Node-level: one graph over two hosts. Two Linux network namespaces joined by a veth pair
(10.200.20.0/30, only inside them) play two computers: the robot's host runs
``flexarm up --only sim,vision,state_publisher``, the other
``flexarm up --only arm_owner,learner,compensator,scene``, both ``--discovery subnet``; a
client on the second host collects 8 samples (the fewest 5-fold cross-validation takes), trains
and reaches a PREDICTIVE goal across them. Then ``flexarm status`` on the robot's host sees both
parts and says which one runs there, and stopping the second host's ``up`` stops only its
part.

Each host has its own FLEXARM_HOME (``config/`` linked; its own data, models and runs) and
TMPDIR (``up``'s domain lock is per machine), as two computers have. The namespaces share
``/dev/shm``, through which Fast DDS's shared-memory transport may reach across them (in a
trial, LOCALHOST-range participants, which announce themselves only on their own machine,
discovered each other across the namespaces), so every process runs with
``FASTDDS_BUILTIN_TRANSPORTS=UDPv4``: all DDS traffic takes the veth, whose byte counters are
checked. Skipped without root or ``ip netns``.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from flexarm_core.paths import CONFIG_DIR

pytestmark = [pytest.mark.node, pytest.mark.timeout(300), pytest.mark.duration(35)]
SUBNET = '10.200.20.{}/30'
ROBOT_SIDE = 'sim,vision,state_publisher'
LEARNING_SIDE = 'arm_owner,learner,compensator,scene'
CLIENT = '''
import json, math
from flexarm_control.ros.client import init_client
client = init_client()
try:
    client.wait_until_ready(timeout=60.0)
    collected = client.collect(8, region='B', dataset='hosts', seed=2, timeout=240.0)
    trained = client.train('gp', dataset='hosts', timeout=120.0)
    if trained.success:
        client.wait_for_model(trained.model_version, timeout=30.0)
    moved = client.move_to(1.15, -0.35, math.radians(-70), mode='predictive', timeout=120.0)
finally:
    client.destroy_node()
print(json.dumps({'collected': collected.collected, 'collect_error': collected.error_string,
                  'trained': trained.success, 'train_message': trained.message,
                  'move_code': moved.error_code, 'move_error': moved.error_string,
                  'position_error': moved.position_error, 'model_version': moved.model_version,
                  'compensation_iterations': moved.compensation_iterations,
                  'data_distance': moved.data_distance,
                  'prediction_std': moved.prediction_std}))
'''


def ip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(['ip', *args], capture_output=True, text=True, timeout=10)


class Hosts:
    """Two network namespaces joined by a veth pair; each end a host with an address."""

    def __init__(self) -> None:
        pid = os.getpid()
        self.ns = (f'flexarm{pid}a', f'flexarm{pid}b')
        self.links = (f'fxa{pid}', f'fxb{pid}')

    def create(self) -> None:
        """Make both hosts; pytest.skip if this machine cannot (no netns, not allowed)."""
        made = ip('netns', 'add', self.ns[0])
        if made.returncode != 0:
            pytest.skip(f'cannot make a network namespace: {made.stderr.strip()}')
        commands = [('netns', 'add', self.ns[1]),
                    ('link', 'add', self.links[0], 'type', 'veth', 'peer', 'name', self.links[1])]
        for i, (ns, link) in enumerate(zip(self.ns, self.links)):
            commands += [('link', 'set', link, 'netns', ns),
                         ('-n', ns, 'addr', 'add', SUBNET.format(i + 1), 'dev', link),
                         ('-n', ns, 'link', 'set', 'lo', 'up'),
                         ('-n', ns, 'link', 'set', link, 'up')]
        for command in commands:
            done = ip(*command)
            assert done.returncode == 0, f'ip {" ".join(command)}: {done.stderr}'

    def traffic(self) -> tuple[int, int]:
        """Bytes the first host's end of the veth sent and received."""
        shown = ip('-n', self.ns[0], '-s', '-j', 'link', 'show', 'dev', self.links[0])
        stats = json.loads(shown.stdout)[0]['stats64']
        return stats['tx']['bytes'], stats['rx']['bytes']

    def remove(self) -> None:
        """Delete both namespaces (their veth ends go with them) and a veth never moved."""
        for ns in self.ns:
            ip('netns', 'delete', ns)
        ip('link', 'delete', self.links[0])


def host_env(home: Path) -> dict[str, str]:
    """Environment of a host's processes: its own flexarm tree and /tmp, DDS over UDP."""
    (home / 'tmp').mkdir(parents=True)
    (home / 'config').symlink_to(CONFIG_DIR)
    return {**os.environ, 'FLEXARM_HOME': str(home), 'FLEXARM_STATE_DIR': str(home),
            'TMPDIR': str(home / 'tmp'),
            'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET', 'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4',
            'PYTHONUNBUFFERED': '1'}


class Up:
    """``flexarm up --only NODES`` in a namespace; its output in ``<home>/up.log``."""

    def __init__(self, ns: str, env: dict[str, str], only: str, domain_id: int) -> None:
        self.log = Path(env['FLEXARM_HOME']) / 'up.log'
        with open(self.log, 'wb') as out:
            self.process = subprocess.Popen(
                ['ip', 'netns', 'exec', ns, sys.executable, '-m', 'flexarm_cli', 'up',
                 '--only', only, '--discovery', 'subnet', '--domain-id', str(domain_id),
                 '--rtf', '10', '--name', 'host', '--timeout', '90'],
                env=env, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                start_new_session=True)

    def text(self) -> str:
        return self.log.read_text(errors='replace')

    def wait_ready(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while 'graph ready' not in self.text():
            if time.monotonic() > deadline or self.process.poll() is not None:
                pytest.fail(f'`up` not ready within {timeout} s:\n{self.text()}')
            time.sleep(0.2)

    def stop(self) -> int | None:
        """SIGINT (``up`` stops its nodes), SIGKILL after 30 s; the exit code."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        try:
            return self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait(timeout=10)
            return None


def run_in(ns: str, env: dict[str, str], args: list[str], timeout: float) -> str:
    """stdout of a command in namespace ``ns``; fails the test if it fails."""
    try:
        done = subprocess.run(['ip', 'netns', 'exec', ns, sys.executable, *args], env=env,
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f'{args[:3]} still ran after {timeout} s: {exc.stdout} {exc.stderr}')
    assert done.returncode == 0, f'{args[:3]} exited {done.returncode}: {done.stderr}'
    return done.stdout


@pytest.mark.skipif(os.geteuid() != 0 or shutil.which('ip') is None,
                    reason='network namespaces need root and iproute2 (`ip netns`)')
def test_one_graph_over_two_hosts(domain_id, tmp_path):
    hosts = Hosts()
    ups: list[Up] = []
    try:
        hosts.create()
        robot_env, learning_env = host_env(tmp_path / 'robot'), host_env(tmp_path / 'learning')
        ups += [Up(hosts.ns[0], robot_env, ROBOT_SIDE, domain_id),
                Up(hosts.ns[1], learning_env, LEARNING_SIDE, domain_id)]
        for up in ups:
            up.wait_ready(90.0)
        assert ('the rest of the graph must run on other hosts: flexarm_arm_owner, '
                'flexarm_learner') in ups[0].text()

        result = json.loads(run_in(hosts.ns[1], learning_env, ['-c', CLIENT], 240.0)
                            .splitlines()[-1])
        assert result['collected'] == 8, result
        assert result['trained'], result
        assert result['move_code'] == 0, result
        assert result['model_version'] and result['compensation_iterations'] >= 1, result
        assert result['position_error'] < 1e-3, result
        assert list((tmp_path / 'learning' / 'data').glob('hosts.jsonl'))
        assert not (tmp_path / 'robot' / 'data').exists()     # learned on the second host
        sent, received = hosts.traffic()
        assert sent > 1e6 and received > 1e4, (sent, received)

        status = json.loads(run_in(hosts.ns[0], robot_env, [
            '-m', 'flexarm_cli', 'status', '--json', '--domain-id', str(domain_id)],
            60.0).splitlines()[-1])
        assert all(status['nodes'][n] for n in ('flexarm_sim', 'flexarm_arm_owner',
                                                'flexarm_learner', 'flexarm_compensator',
                                                'flexarm_scene'))
        assert set(status['supervisor']['nodes']) == {
            'flexarm_sim', 'flexarm_vision', 'flexarm_state_publisher'}
        assert status['supervisor']['remote'] == [
            'flexarm_arm_owner', 'flexarm_learner', 'flexarm_compensator', 'flexarm_scene']

        assert ups[1].stop() == 0
        assert 'stopped: flexarm_arm_owner (0), flexarm_learner (0)' in ups[1].text()
        time.sleep(1.0)
        assert ups[0].process.poll() is None            # the robot's host runs on
    finally:
        codes = [up.stop() for up in ups]
        hosts.remove()
    assert codes == [0, 0], [up.text()[-2000:] for up in ups]
