"""``flexarm status`` without a graph: the supervisor record and the text an operator reads."""
import json
import os

from flexarm_bringup.graph_status import graph_node_names, status_text, supervisor_record

MODEL = {'version': '4', 'kind': 'gp', 'dataset': 'B', 'payloads': [0.0], 'samples': 40,
         'validation': '5-fold cross-validation', 'max_error': [1e-4, 2e-4, 1e-5],
         'warning': '', 'path': '/m/B-gp-v4.model', 'age_s': 7200.0}


def status(**changes):
    nodes = dict.fromkeys(graph_node_names(), False)
    nodes.update(flexarm_sim=True, flexarm_compensator=True, flexarm_learner=True)
    return {'domain_id': 42, 'nodes': nodes, 'controller': 'sim', 'joint_state_rate_hz': 99.0,
            'learner_model': MODEL, 'active_model': MODEL,
            'payload_kg': {'learner': 0.0, 'simulated': 5.0}, 'bag': None} | changes


def test_the_live_supervisor_of_the_domain_is_found(tmp_path):
    for name, pid, domain in (('old', 2 ** 22 + 1, 42), ('other', os.getpid(), 7),
                              ('live', os.getpid(), 42)):
        (tmp_path / name).mkdir()
        (tmp_path / name / 'graph.json').write_text(json.dumps({
            'supervisor_pid': pid, 'domain_id': domain, 'robot': 'sim',
            'nodes': {'flexarm_vision': {'pid': 1, 'restarts': 2, 'exit_code': None}}}))
    (tmp_path / 'torn').mkdir()
    (tmp_path / 'torn' / 'graph.json').write_text('{"supervisor_pid": ')
    record = supervisor_record(tmp_path, 42)
    assert record['run_dir'] == str(tmp_path / 'live')
    assert supervisor_record(tmp_path, 43) is None


def test_the_text_says_what_drives_the_arm():
    record = {'supervisor_pid': 1, 'robot': 'sim', 'run_dir': 'runs/x',
              'nodes': {'flexarm_compensator': {'restarts': 1}}}
    text = status_text(status(), record)
    assert 'ROS_DOMAIN_ID=42' in text and 'flexarm_compensator (restarted 1x)' in text
    assert 'model driving the arm (compensator): v4 gp, dataset B, 40 samples at 0 kg' in text
    assert '0.100 mm, 0.200 mm' in text and 'trained 2.0 h ago' in text
    assert 'NOT in use' not in text and 'learner 0 kg, simulated 5 kg' in text
    other = MODEL | {'version': '5', 'warning': 'trained at payload 5 kg, the arm carries 0 kg'}
    text = status_text(status(learner_model=other, active_model=None), None)
    assert 'model driving the arm (compensator): none' in text
    assert 'announced by the learner (NOT in use): v5' in text and 'WARNING: trained' in text
    assert 'supervisor: none found' in text


def test_an_empty_domain_says_how_to_start_a_graph():
    empty = status(nodes=dict.fromkeys(graph_node_names(), False), controller=None,
                   learner_model=None, active_model=None,
                   payload_kg={'learner': None, 'simulated': None})
    text = status_text(empty, None)
    assert 'no flexarm graph in this domain' in text and 'flexarm up' in text
    assert 'controller: none' in text and 'payload: unknown' in text
