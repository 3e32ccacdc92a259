"""Node process specs and environments of the orchestrator."""
import sys

import pytest
import yaml

from flexarm_control.launcher import NodeSpec, load_graph, node_command, ros_env, write_overrides
from flexarm_control.params import config_path


def test_node_command_names_the_node_and_its_params(tmp_path) -> None:
    spec = NodeSpec(name='n', module='pkg.mod', params_files=('arm.yaml',),
                    parameters={'use_sim_time': True, 'rate': 2.5})
    overrides = write_overrides(spec, {'topics': ['/a', '/b'], 'rate': 3.0}, tmp_path / 'n.yaml')
    cmd = node_command(spec, overrides)
    assert cmd[:5] == [sys.executable, '-m', 'pkg.mod', '--ros-args', '-r']
    assert cmd[5] == '__node:=n'
    files = [cmd[i + 1] for i, a in enumerate(cmd) if a == '--params-file']
    assert files == [str(config_path('arm.yaml')), str(overrides)]
    assert yaml.safe_load(overrides.read_text()) == {'n': {'ros__parameters': {
        'use_sim_time': True, 'rate': 3.0, 'topics': ['/a', '/b']}}}
    assert write_overrides(NodeSpec(name='m', module='x'), None, tmp_path / 'm.yaml') is None


def test_run_parameters_win_over_node_specific_config_entries(tmp_path) -> None:
    """rcl gives a node-specific params-file entry precedence over ``-p``; ours come last."""
    import rclpy
    from rclpy.context import Context

    spec = {s.name: s for s in load_graph('sim')}['flexarm_learner']
    overrides = write_overrides(spec, {'data_directory': '/elsewhere'}, tmp_path / 'l.yaml')
    context = Context()
    rclpy.init(context=context, args=node_command(spec, overrides)[3:], domain_id=0)
    try:
        node = rclpy.create_node('flexarm_learner', context=context,
                                 automatically_declare_parameters_from_overrides=True)
        assert node.get_parameter('data_directory').value == '/elsewhere'
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


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
