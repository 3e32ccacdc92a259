"""Parameters declared from the shipped file that is their schema: its defaults, descriptions,
types and ranges; the params files a node was given supply the values."""
from __future__ import annotations

import pytest
import rclpy
from rclpy.context import Context
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.parameter import Parameter

from flexarm_core.parameter_schema import node_schema
from flexarm_core.params import config_path, flatten, load_config, unflatten
from flexarm_core.ros.node_params import declare, declare_tree


@pytest.fixture
def node(request):
    """A node named ``request.param[0]`` started with the ROS arguments that follow."""
    name, *args = request.param
    context = Context()
    rclpy.init(context=context, args=['--ros-args', *args])
    node = rclpy.create_node(name, context=context)
    yield node
    node.destroy_node()
    rclpy.shutdown(context=context)


@pytest.mark.parametrize('node', [['flexarm_test', '--params-file', str(config_path('arm.yaml')),
                                   '-p', 'arm.link3:=0.5']], indirect=True)
def test_a_tree_has_the_shipped_names_and_the_given_values(node):
    tree = declare_tree(node, 'arm', 'config/arm.yaml')
    expected = load_config('arm.yaml')['arm']
    expected['link3'] = 0.5
    assert tree == expected
    described = node.describe_parameter('arm.link3')
    assert described.read_only
    assert described.description == '[m] L2 of Table 1, joint3 -> joint4'


@pytest.mark.parametrize('node', [['flexarm_test']], indirect=True)
def test_a_node_given_no_file_gets_the_shipped_defaults(node):
    assert declare_tree(node, 'arm', 'config/arm.yaml') == load_config('arm.yaml')['arm']
    assert declare(node, 'sim_clock', 'config/clock.yaml', read_only=True) is False
    assert node.describe_parameter('sim_clock').read_only


@pytest.mark.parametrize('node', [['flexarm_test']], indirect=True)
def test_only_the_dynamic_names_of_a_tree_are_writable(node):
    declare_tree(node, 'camera', 'config/camera.yaml', dynamic={'offset'})
    assert node.set_parameters([Parameter('camera.offset', value=[0.02, 0.0])])[0].successful
    assert not node.set_parameters([Parameter('camera.fx', value=500.0)])[0].successful


@pytest.mark.parametrize('node', [['flexarm_bridge']], indirect=True)
def test_the_descriptor_carries_the_files_description_and_range(node):
    assert declare(node, 'port', 'config/bridge.yaml') == 47800
    assert declare(node, 'heartbeat_timeout', 'config/bridge.yaml') == 1.0
    port, timeout = node.describe_parameters(['port', 'heartbeat_timeout'])
    assert port.description == node_schema(config_path('bridge.yaml'),
                                           'flexarm_bridge')['port'].description
    assert 'TCP port' in port.description
    assert [(r.from_value, r.to_value) for r in port.integer_range] == [(1, 65535)]
    assert [(r.from_value, r.to_value) for r in timeout.floating_point_range] == [(0.05, 60.0)]
    assert not port.read_only


@pytest.mark.parametrize('node', [['flexarm_bridge', '-p', 'max_errors:=0']], indirect=True)
def test_a_value_outside_the_range_is_refused_given_or_set(node):
    with pytest.raises(InvalidParameterValueException):
        declare(node, 'max_errors', 'config/bridge.yaml')
    assert declare(node, 'retry_max', 'config/bridge.yaml') == 5.0
    refused = node.set_parameters([Parameter('retry_max', value=601.0)])[0]
    assert not refused.successful and node.get_parameter('retry_max').value == 5.0
    assert node.set_parameters([Parameter('retry_max', value=600.0)])[0].successful


@pytest.mark.parametrize('node', [['flexarm_bridge', '-p', 'port:=high']], indirect=True)
def test_a_value_of_another_type_is_refused(node):
    with pytest.raises(InvalidParameterTypeException):
        declare(node, 'port', 'config/bridge.yaml')


@pytest.mark.parametrize('node', [['flexarm_test']], indirect=True)
def test_a_name_the_file_does_not_hold_for_the_node_is_an_error(node):
    with pytest.raises(ValueError, match='config/bridge.yaml defines no parameter retry_min '
                                         'for flexarm_test'):
        declare(node, 'retry_min', 'config/bridge.yaml')     # the bridge's own section
    with pytest.raises(ValueError, match='defines no "nothing.\\*" parameters'):
        declare_tree(node, 'nothing', 'config/arm.yaml')


def test_flatten_inverts_unflatten():
    tree = load_config('camera.yaml')['camera']
    assert unflatten(flatten(tree)) == tree
    assert flatten({'a': {'b': [1, 2], 'c': {'d': 'x'}}}) == {'a.b': [1, 2], 'a.c.d': 'x'}
