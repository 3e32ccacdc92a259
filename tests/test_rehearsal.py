"""Node-level: a site's real arm, rehearsed. A site folder (`flexarm site init`) sets the
controller link; the rehearsal program (the fake controller and its tip camera, on the wall
clock, as a vendor's controller would run) starts first; `flexarm up --robot bridge --site DIR`
starts the bridge and nothing simulated, every node on wall time. Then the whole loop:
calibrate, collect, train, PREDICTIVE and CLOSED_LOOP goals. Nothing in the clone changes.
"""
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
import rclpy
from rclpy.context import Context

from flexarm_bridge.link_auth import make_key
from flexarm_control.ros.client import FlexarmClient
from flexarm_core import liveness
from flexarm_core.paths import SOURCE
from flexarm_msgs.action import MoveToPose

pytestmark = [pytest.mark.node, pytest.mark.duration(120)]
GATED = 'import os, sys; sys.stdin.readline(); os.execv(sys.argv[1], sys.argv[1:])'
UP_S, GONE_S = 60.0, 30.0      # [s, liveness-scaled] to start; to end after SIGINT
NODES = ('flexarm_bridge', 'flexarm_arm_owner', 'flexarm_vision', 'flexarm_learner',
         'flexarm_compensator', 'flexarm_state_publisher', 'flexarm_scene')
TARGET = (1.30, -0.20, math.radians(-61))          # Table 10, B6


STATE = ('config', 'calibration', 'data', 'models', 'runs', 'bags', 'results')


def clone_files() -> dict[str, float]:
    """What a site's run could write in the clone: config/ and the (git-ignored) state
    folders, by path and modification time."""
    return {str(path): path.stat().st_mtime for folder in STATE
            for path in (SOURCE / folder).rglob('*') if path.is_file()}


def flexarm(*args: str, env: dict[str, str], **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'flexarm_cli', *args], env=env,
                          capture_output=True, text=True, **kwargs)


def test_a_rehearsed_site_runs_the_whole_loop_on_wall_time(launch, domain_id, domain_pool,
                                                             tmp_path):
    before = clone_files()
    site = tmp_path / 'site'
    env = {k: v for k, v in os.environ.items() if k != 'FLEXARM_STATE_DIR'}   # the site's
    # this test's graph lock apart from other tests' (a second shell finds the one graph)
    env.update(FLEXARM_SITE=str(site), PYTHONUNBUFFERED='1', TMPDIR=str(tmp_path))
    second_shell = {k: v for k, v in env.items() if k not in ('FLEXARM_SITE', 'ROS_DOMAIN_ID')}
    made = flexarm('site', 'init', str(site), '--robot', 'bridge', env=env, check=True)
    assert 'config/bridge.yaml' in made.stdout
    port, key = 47000 + 2 * domain_id, make_key(tmp_path / 'site.key')
    bridge = site / 'config' / 'bridge.yaml'
    bridge.write_text(bridge.read_text().replace('47800', str(port)).replace(
        "link_key_file: ''", f'link_key_file: {key}'))
    launch('flexarm_fake_controller', robot='bridge', port=port, link_key_file=str(key))
    up = subprocess.Popen(
        [sys.executable, '-c', GATED, sys.executable, '-m', 'flexarm_cli', 'up',
         '--robot', 'bridge', '--domain-id', str(domain_id), '--timeout',
         str(liveness.limit(UP_S))], env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True)
    context = Context()
    with domain_pool.lent(domain_id):
        up.stdin.write('go\n')
        up.stdin.flush()
        try:
            line = up.stdout.readline()
            assert 'flexarm_bridge' in line and 'flexarm_sim' not in line, (
                line, up.stderr.read() if not line else '')
            assert 'flexarm_fake_controller' not in line           # nothing simulated
            ready = up.stdout.readline()
            assert 'graph ready' in ready, (ready, up.stderr.read() if not ready else '')
            # a second shell that names neither the site nor the domain: the graph's, found
            calibrated = flexarm('calibrate', env=second_shell,
                                 timeout=liveness.limit(120.0))
            assert calibrated.returncode == 0, calibrated.stderr
            assert f'ROS_DOMAIN_ID={domain_id}' in calibrated.stderr, calibrated.stderr
            assert str(site / 'calibration' / 'tool_camera.json') in calibrated.stdout
            rclpy.init(context=context, domain_id=domain_id)
            client = FlexarmClient('rehearsal_test', context=context)
            try:
                client.wait_until_ready(30.0)
                assert not any(client.node_parameter(name, 'use_sim_time')
                               for name in NODES), 'a node on sim time'
                collected = client.collect(10, region='B', dataset='b', seed=2, timeout=180)
                assert collected.error_code == 0, collected.error_string
                assert Path(collected.dataset_path).is_relative_to(site / 'data')
                trained = client.train('', dataset='b', timeout=60)
                assert trained.success, trained.message
                client.wait_for_model(trained.model_version, timeout=10)
                predictive = client.move_to(*TARGET, mode='predictive', timeout=120)
                closed = client.move_to(*TARGET, mode='closed_loop', timeout=120)
            finally:
                client.destroy_node()
                rclpy.try_shutdown(context=context)
        finally:
            up.send_signal(2)
            try:
                up.communicate(timeout=liveness.limit(GONE_S))
            except subprocess.TimeoutExpired:
                up.kill()
                pytest.fail('flexarm up did not stop on SIGINT')
    assert predictive.error_code == closed.error_code == MoveToPose.Result.SUCCESSFUL, (
        predictive.error_string, closed.error_string)
    assert predictive.position_error < predictive.position_error_bound
    assert closed.position_error <= 5e-5 + 1e-9                 # the default tolerance
    [log] = site.glob('runs/*/flexarm_bridge.log')
    assert 'link authenticated' in log.read_text()
    assert clone_files() == before                               # nothing in the clone
    assert (site / 'runs').is_dir() and (site / 'models').is_dir()
