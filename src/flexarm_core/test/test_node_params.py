"""Parameter trees declared from the params files a node was given."""
from __future__ import annotations

import pytest
import rclpy
from rclpy.context import Context
from rclpy.exceptions import InvalidParameterValueException
from rclpy.parameter import Parameter

from flexarm_core.params import config_path, flatten, load_config, unflatten
from flexarm_core.ros.node_params import declare, declare_tree


@pytest.fixture
def context(request):
    context = Context()
    rclpy.init(context=context, args=['--ros-args', *request.param])
    yield context
    rclpy.shutdown(context=context)


@pytest.mark.parametrize('context', [['--params-file', str(config_path('arm.yaml')),
                                      '-p', 'arm.link3:=0.5']], indirect=True)
def test_a_tree_has_the_shipped_names_and_the_given_values(context):
    node = rclpy.create_node('flexarm_test', context=context)
    try:
        tree = declare_tree(node, 'arm', 'config/arm.yaml')
        expected = load_config('arm.yaml')['arm']
        expected['link3'] = 0.5
        assert tree == expected
        assert node.describe_parameter('arm.link3').read_only
    finally:
        node.destroy_node()


@pytest.mark.parametrize('context', [[]], indirect=True)
def test_a_tree_not_given_names_the_file_to_pass(context):
    node = rclpy.create_node('flexarm_test', context=context)
    try:
        with pytest.raises(ValueError, match='pass --params-file config/arm.yaml'):
            declare_tree(node, 'arm', 'config/arm.yaml')
    finally:
        node.destroy_node()


def test_flatten_inverts_unflatten():
    tree = load_config('sim.yaml')['plant']
    assert unflatten(flatten(tree)) == tree
    assert flatten({'a': {'b': [1, 2], 'c': {'d': 'x'}}}) == {'a.b': [1, 2], 'a.c.d': 'x'}


@pytest.mark.parametrize('context', [['-p', 'rate:=5000.0']], indirect=True)
def test_a_value_outside_the_bounds_is_refused_given_or_set(context):
    node = rclpy.create_node('flexarm_test', context=context)
    try:
        with pytest.raises(InvalidParameterValueException):
            declare(node, 'rate', 25.0, '[Hz]', bounds=(0.1, 1000.0))
        assert declare(node, 'count', 8, 'samples', bounds=(1, 100)) == 8
        refused = node.set_parameters([Parameter('count', value=0)])[0]
        assert not refused.successful and node.get_parameter('count').value == 8
        assert node.set_parameters([Parameter('count', value=100)])[0].successful
    finally:
        node.destroy_node()
