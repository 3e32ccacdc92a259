"""What ends `flexarm status`'s waits and what it makes of what it heard, without a graph:
the supervisor record's live nodes, the joint-state rate, the latched model messages the
nodes' reports announce, the simulator's real-time factor, and the other arms of a domain."""
from __future__ import annotations

import pytest

from flexarm_bringup.graph_status import (
    graph_node_names,
    joint_state_rate,
    latched_in,
    record_nodes,
)
from flexarm_bringup.status_text import Heard, real_time_factor, status_text
from flexarm_core.health_report import OK

RECORD = {'supervisor_pid': 1, 'robot': 'sim', 'run_dir': 'runs/x', 'remote': ['flexarm_learner'],
          'nodes': {'flexarm_sim': {'pid': 10, 'restarts': 0, 'exit_code': None},
                    'flexarm_vision': {'pid': 11, 'restarts': 0, 'exit_code': None},
                    'flexarm_compensator': {'pid': 12, 'restarts': 3, 'exit_code': -9}}}


def test_the_records_live_nodes_run_here_and_its_remote_ones_must_be_discovered():
    here, remote = record_nodes(RECORD, alive=lambda pid: pid != 11)
    assert here == {'flexarm_sim'} and remote == {'flexarm_learner'}
    assert record_nodes(None) == (set(), set())


def test_the_joint_state_rate_comes_from_the_arrivals():
    assert joint_state_rate([0.0, 0.01, 0.02, 0.03, 0.04]) == pytest.approx(100.0)
    assert joint_state_rate([0.5]) == 0.0 and joint_state_rate([]) == 0.0
    # bursts whose oldest messages were dropped: the rate of the stamps, not of what came
    assert joint_state_rate([0.0, 0.01, 0.02, 0.35, 0.36, 0.37, 0.38, 0.75, 0.76]) == \
        pytest.approx(100.0)


def _model(version: str) -> Heard:
    return Heard(OK, '', {'version': version})


def test_latched_models_are_awaited_only_where_a_node_reports_one():
    none = {'flexarm_learner: model': _model(''), 'flexarm_compensator: model': _model('')}
    assert latched_in(none, {}, None)
    learner = none | {'flexarm_learner: model': _model('3')}
    assert not latched_in(learner, {}, None)
    assert latched_in(learner, {'learner': object()}, None)
    compensator = none | {'flexarm_compensator: model': _model('3')}
    assert not latched_in(compensator, {'health': object()}, None)
    assert not latched_in(compensator, {}, object())         # its health still to come
    assert latched_in(compensator, {'health': object()}, object())


def test_the_simulators_real_time_factor_is_read_from_its_report():
    report = Heard(OK, 'arm still, x4.87 real time (set x10)',
                   {'real-time factor': '4.87', 'real-time factor set': '10.0'})
    assert real_time_factor(report) == {'achieved': 4.87, 'set': 10.0}
    assert real_time_factor(None) is None
    assert real_time_factor(Heard(OK, 'bridge', {})) is None


def _status(**changes) -> dict:
    nodes = dict.fromkeys(graph_node_names(), False) | {'flexarm_sim': True}
    return {'domain_id': 7, 'nodes': nodes, 'controller': 'sim', 'joint_state_rate_hz': 100.0,
            'real_time_factor': {'achieved': 4.87, 'set': 10.0}, 'arms': [''],
            'learner_model': None, 'active_model': None,
            'payload_kg': {'learner': None, 'simulated': None}, 'bag': None} | changes


def test_the_text_shows_the_real_time_factor_achieved_and_set():
    text = status_text(_status(), None)
    assert 'controller: sim, joint states at 100 Hz, x4.87 real time (set x10)' in text
    text = status_text(_status(controller='bridge', real_time_factor=None), None)
    assert 'controller: bridge, joint states at 100 Hz\n' in text


def test_a_domain_of_namespaced_arms_is_named_not_reported_empty():
    nodes = dict.fromkeys(graph_node_names(), False)
    text = status_text(_status(nodes=nodes, controller=None, arms=['arm1', 'arm2']), None)
    assert ('nodes up: none in this namespace; the domain runs 2 arm(s) elsewhere: arm1, arm2 '
            '(pass --namespace NS)') in text
    assert 'NO joint states' not in text
    text = status_text(_status(nodes=nodes, controller=None, arms=[]), None)
    assert 'none: no flexarm graph in this domain' in text
