"""Node process specs and environments of the orchestrator."""
import sys

import pytest

from flexarm_control.launcher import NodeSpec, load_graph, node_command, ros_env
from flexarm_control.params import config_path


def test_node_command_names_the_node_and_its_params() -> None:
    spec = NodeSpec(name='n', module='pkg.mod', params_files=('arm.yaml',),
                    parameters={'use_sim_time': True, 'rate': 2.5})
    cmd = node_command(spec, {'topics': ['/a', '/b'], 'name': 'x y'})
    assert cmd[:5] == [sys.executable, '-m', 'pkg.mod', '--ros-args', '-r']
    assert cmd[5] == '__node:=n'
    assert cmd[cmd.index('--params-file') + 1] == str(config_path('arm.yaml'))
    overrides = [cmd[i + 1] for i, a in enumerate(cmd) if a == '-p']
    assert overrides == ['use_sim_time:=true', 'rate:=2.5', "topics:=[/a, /b]", 'name:=x y']


def test_ros_env_isolates_the_domain_and_drops_the_bootstrap_guard() -> None:
    env = ros_env(42, base={'_ROS_WHEELS_BOOTSTRAP_COMPLETE': '1', 'PATH': '/bin'})
    assert env['ROS_DOMAIN_ID'] == '42'
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    assert '_ROS_WHEELS_BOOTSTRAP_COMPLETE' not in env
    assert env['PATH'] == '/bin'


def test_graph_has_one_controller_and_the_control_nodes() -> None:
    names = [s.name for s in load_graph('sim')]
    assert names[0] == 'flexarm_sim'
    assert {'flexarm_vision', 'flexarm_learner', 'flexarm_compensator'} <= set(names)
    with pytest.raises(ValueError, match='unknown robot'):
        load_graph('nonexistent')
