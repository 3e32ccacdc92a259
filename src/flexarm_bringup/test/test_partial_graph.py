"""A graph split over hosts (``flexarm up --only``): which nodes a host starts, which it
expects from the others, when it is ready and what it says when it is not."""
import contextlib

import pytest

from flexarm_bringup.launcher import select_nodes
from flexarm_bringup.status_text import status_text
from flexarm_bringup.supervisor import (
    ACTION_STATUS,
    READY_ACTIONS,
    READY_SERVICES,
    READY_TOPICS,
    Graph,
    ready_topics,
)
from flexarm_core import topics

CORE = ['flexarm_sim', 'flexarm_vision', 'flexarm_learner', 'flexarm_compensator']


def test_only_picks_nodes_by_short_or_full_name_in_graph_order():
    assert select_nodes(CORE, ['learner', ' flexarm_sim']) == ['flexarm_sim', 'flexarm_learner']
    assert select_nodes(CORE, ['vision', 'vision']) == ['flexarm_vision']
    with pytest.raises(ValueError, match='unknown node.s. camera, bridge; the graph has sim, '
                                         'vision, learner, compensator'):
        select_nodes(CORE, ['sim', 'camera', 'bridge'])
    with pytest.raises(ValueError, match='none given'):
        select_nodes(CORE, ['', ' '])


def test_a_host_starts_its_part_and_expects_the_rest_of_the_graph(tmp_path):
    robot_side = Graph(0, tmp_path, only=('sim', 'vision', 'recorder'))
    assert list(robot_side.nodes) == ['flexarm_sim', 'flexarm_vision', 'flexarm_recorder']
    assert robot_side.remote == ('flexarm_arm_owner', 'flexarm_learner', 'flexarm_compensator',
                                 'flexarm_state_publisher', 'flexarm_scene')
    learning_side = Graph(0, tmp_path, only=('flexarm_learner',), optional=('flexarm_foxglove',))
    assert list(learning_side.nodes) == ['flexarm_learner', 'flexarm_foxglove']
    assert 'flexarm_recorder' not in learning_side.remote            # optional: never expected
    assert Graph(0, tmp_path).remote == ()
    bridge = Graph(0, tmp_path, robot='bridge', only=('compensator',))
    assert bridge.remote[:2] == ('flexarm_bridge', 'flexarm_arm_owner')   # nothing simulated
    with pytest.raises(ValueError, match='unknown node.s. sim'):
        Graph(0, tmp_path, robot='bridge', only=('sim',))


class Probe:
    """What the supervisor's probe node discovers: these nodes, and every ready interface
    but ``lacking``."""

    def __init__(self, nodes, lacking=()):
        self.nodes = nodes
        names = [topics.absolute(n) for n in (*READY_TOPICS, topics.CLOCK, *READY_SERVICES)]
        names += [topics.absolute(a) + '/_action/send_goal' for a in READY_ACTIONS]
        names.append(topics.absolute(ACTION_STATUS.format(topics.FOLLOW_JOINT_TRAJECTORY)))
        self.names = [n for n in names if n not in lacking]
        self.lacking = lacking

    def get_node_names_and_namespaces(self):
        return [(name, '/') for name in self.nodes]

    def get_topic_names_and_types(self):
        return [(name, ['t']) for name in self.names]

    get_service_names_and_types = get_topic_names_and_types

    def count_publishers(self, name):
        return int(name in self.names)

    def count_subscribers(self, name):
        return int(name not in self.lacking)


@pytest.fixture
def discovering(monkeypatch):
    """``discovering(probe)``: the graph's discovery sees what ``probe`` holds."""
    def use(probe):
        monkeypatch.setattr(Graph, '_probe', lambda self: contextlib.nullcontext(probe))
    return use


def test_a_partial_graph_is_ready_only_with_the_remote_nodes_and_names_what_lacks(
        tmp_path, discovering):
    graph = Graph(17, tmp_path, only=('arm_owner', 'learner', 'compensator', 'scene'))
    everything = [*graph.nodes, *graph.remote]
    discovering(Probe(list(graph.nodes)))                       # the other host is not up
    with pytest.raises(TimeoutError) as refused:
        graph.wait_ready(0.3)
    text = str(refused.value)
    assert 'remote node flexarm_sim, remote node flexarm_vision' in text
    assert 'remote node flexarm_state_publisher' in text and 'node flexarm_learner' not in text
    assert ('flexarm_sim, flexarm_vision, flexarm_state_publisher must run on other hosts in '
            'ROS_DOMAIN_ID=17') in text and '--discovery subnet or ROS_STATIC_PEERS' in text

    train = topics.absolute(READY_SERVICES[0])
    discovering(Probe(everything, lacking=(train,)))          # all nodes, one server missing
    with pytest.raises(TimeoutError, match=f'missing {train} '):
        graph.wait_ready(0.3)

    discovering(Probe(everything))
    graph.wait_ready(5.0)                                       # returns: ready


def test_a_ros2_control_arm_is_ready_on_wall_time_with_a_trajectory_controller_serving(
        tmp_path, discovering):
    """No simulator, no bridge, no /clock: the integrator's controller_manager and camera
    driver are the robot; the learner and the compensator send FollowJointTrajectory goals on
    wall time, so the graph waits for the controller's action server."""
    assert ready_topics({'use_sim_time': True, 'motion.joint_commands': 'forward'}) == (
        (*READY_TOPICS, topics.CLOCK), (topics.JOINT_COMMANDS,))
    assert ready_topics({'use_sim_time': True, 'motion.joint_commands': 'trajectory'}) == (
        (*READY_TOPICS, topics.CLOCK), (topics.JOINT_TRAJECTORY,))
    graph = Graph(17, tmp_path, robot='ros2_control')
    assert not {'flexarm_sim', 'flexarm_bridge'} & set(graph.nodes)
    for name in ('flexarm_learner', 'flexarm_compensator'):
        assert graph.nodes[name].spec.parameters == {
            'use_sim_time': False, 'motion.joint_commands': 'follow_joint_trajectory'}
    status = topics.absolute(ACTION_STATUS.format(topics.FOLLOW_JOINT_TRAJECTORY))
    discovering(Probe(list(graph.nodes), lacking=(topics.CLOCK, status)))
    with pytest.raises(TimeoutError) as refused:
        graph.wait_ready(0.3)
    assert str(refused.value).endswith(f'missing {status}')
    discovering(Probe(list(graph.nodes), lacking=(topics.CLOCK,)))
    graph.wait_ready(5.0)                                       # ready without /clock


def test_a_whole_graph_names_no_remote_part(tmp_path, discovering):
    graph = Graph(17, tmp_path)
    discovering(Probe(CORE))
    with pytest.raises(TimeoutError) as refused:
        graph.wait_ready(0.3)
    assert 'node flexarm_scene' in str(refused.value)
    assert 'remote' not in str(refused.value) and 'other hosts' not in str(refused.value)


def test_status_says_which_part_runs_here():
    record = {'supervisor_pid': 1, 'robot': 'sim', 'run_dir': 'runs/x',
              'nodes': {'flexarm_sim': {'restarts': 0}, 'flexarm_vision': {'restarts': 0}},
              'remote': ['flexarm_learner', 'flexarm_compensator']}
    status = {'domain_id': 42, 'nodes': {'flexarm_sim': True, 'flexarm_learner': True},
              'controller': 'sim', 'joint_state_rate_hz': 100.0, 'learner_model': None,
              'active_model': None, 'payload_kg': {'learner': 0.0, 'simulated': 0.0},
              'bag': None}
    text = status_text(status, record)
    assert ('part of the graph: flexarm_sim, flexarm_vision here; flexarm_learner, '
            'flexarm_compensator on other hosts') in text
    assert 'part of the graph' not in status_text(status, record | {'remote': []})
