"""``flexarm status`` without a graph: the supervisor record and the text an operator reads."""
import json
import os
from pathlib import Path

from flexarm_bringup.graph_status import (
    ErrorLog,
    arm_status_name,
    file_summary,
    graph_node_names,
    graph_problems,
    supervisor_record,
)
from flexarm_bringup.graph_watch import FirstReports
from flexarm_bringup.status_text import (
    Heard,
    calibration_text,
    clock_text,
    model_line,
    starting_model_text,
    status_text,
)
from flexarm_core.health_report import ERROR, OK, WARN

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
    assert 'model health: none (no model in use)' in text
    assert 'model health: not heard' in status_text(status(), None)
    alone = status()
    alone['nodes'] = alone['nodes'] | {'flexarm_compensator': False}
    assert 'model health: none (no compensator)' in status_text(alone, None)
    assert 'announced by the learner (NOT in use): v5' in text and 'WARNING: trained' in text
    assert 'supervisor: none found' in text


def test_an_empty_domain_says_how_to_start_a_graph():
    empty = status(nodes=dict.fromkeys(graph_node_names(), False), controller=None,
                   learner_model=None, active_model=None,
                   payload_kg={'learner': None, 'simulated': None})
    text = status_text(empty, None)
    assert 'no flexarm graph in this domain' in text and 'flexarm up' in text
    assert 'controller: none' in text and 'payload: unknown' in text


def test_statuses_of_this_arm_are_told_from_other_arms_and_other_software():
    assert arm_status_name('flexarm_vision: camera_info', '') == 'flexarm_vision: camera_info'
    assert arm_status_name('arm1/flexarm_vision: camera_info', '') is None
    assert arm_status_name('arm1/flexarm_vision: camera_info', '/arm1') == (
        'flexarm_vision: camera_info')
    assert arm_status_name('arm2/flexarm_vision: camera_info', 'arm1') is None
    assert arm_status_name('flexarm_vision: camera_info', 'arm1') is None
    assert arm_status_name('joy_node: joystick', '') is None


def test_problems_name_dead_nodes_of_the_record_then_errors():
    record = {'run_dir': '/runs/x', 'nodes': {
        'flexarm_sim': {'pid': 10, 'restarts': 0, 'exit_code': -9},
        'flexarm_vision': {'pid': 11, 'restarts': 1, 'exit_code': None},
        'flexarm_learner': {'pid': 12, 'restarts': 0, 'exit_code': None}}}
    errors = {'flexarm_vision: tool calibration': '/c/tool_camera.json is damaged (x)'}
    problems = graph_problems(errors, record, alive=lambda pid: pid == 12)
    assert problems == [
        'flexarm_sim is down: it exited with code -9 and was not restarted (its log: '
        '/runs/x/flexarm_sim.log)',
        'flexarm_vision is down: its process 11 is gone',
        'flexarm_vision: tool calibration: /c/tool_camera.json is damaged (x)']
    assert graph_problems({}, None) == []
    silent = graph_problems({}, None, silent_controller='sim')
    assert len(silent) == 1 and silent[0].startswith('controller sim: no joint states for')


def test_the_text_says_who_publishes_the_clock():
    follows = Heard(OK, 'arm still', {'clock': 'follows the /clock of /arm1/flexarm_sim',
                                      'sim time [s]': '150.2'})
    said = clock_text(follows)
    assert said == 'the simulator follows the /clock of /arm1/flexarm_sim, at sim time 150.2 s'
    assert f'clock: {said}' in status_text(status(clock=said), None)
    assert clock_text(None) is None and clock_text(Heard(OK, 'arm still', {})) is None
    assert 'clock:' not in status_text(status(), None)


def test_each_error_is_said_once_and_when_it_is_over():
    log = ErrorLog()
    broken = Heard(ERROR, 'file damaged')
    assert log.update({'flexarm_vision: tool calibration': broken,
                       'flexarm_sim: controller': Heard(WARN, 'moving')}) == [
        'PROBLEM flexarm_vision: tool calibration: file damaged']
    assert log.update({'flexarm_vision: tool calibration': broken}) == []
    assert log.update({'flexarm_vision: tool calibration': Heard(ERROR, 'other reason')}) == [
        'PROBLEM flexarm_vision: tool calibration: other reason']
    assert log.update({'flexarm_vision: tool calibration': Heard(OK, 'from file')}) == [
        'resolved flexarm_vision: tool calibration: OK from file']
    assert log.update({'flexarm_vision: tool calibration': Heard(OK, 'from file')}) == []


def test_the_starting_model_waits_for_the_compensator_unless_the_learner_has_none():
    announced = Heard(OK, 'model v4 (gp) announced', {'version': '4'})
    assert starting_model_text(None, None) is None                 # nothing heard yet
    assert starting_model_text(None, announced) is None            # loading it
    assert starting_model_text(MODEL, announced).startswith('model driving the arm: v4 gp')
    assert 'none yet' in starting_model_text(None, Heard(OK, 'no model yet', {'version': ''}))
    damaged = Heard(ERROR, 'no model announced: current.json is damaged', {'version': ''})
    assert 'could not announce one (PROBLEM below)' in starting_model_text(None, damaged)


def test_problems_end_the_status_text():
    assert status_text(status(), None).endswith('problems: none')
    text = status_text(status(problems=['flexarm_sim is down: it exited with code -9']), None)
    assert text.endswith('PROBLEMS:\n  flexarm_sim is down: it exited with code -9')


class FakeWatch:
    """A GraphWatch whose statuses the test sets; spinning only counts."""

    def __init__(self) -> None:
        self.statuses: dict[str, Heard] = {}
        self.spins, self.closed = 0, False

    def spin(self, seconds: float) -> None:
        self.spins += 1

    def forget(self, nodes) -> None:
        self.statuses = {n: h for n, h in self.statuses.items() if n.split(': ')[0] not in nodes}

    def close(self) -> None:
        self.closed = True


def test_first_reports_listen_until_each_node_has_reported_once():
    watches, said = [], []
    reports = FirstReports(lambda: watches.append(FakeWatch()) or watches[-1], said.append)
    watch = reports.expect(['flexarm_vision', 'flexarm_learner', 'flexarm_foxglove'], 60.0)
    watch.statuses['flexarm_vision: tool calibration'] = Heard(ERROR, 'damaged')
    reports.step(0.5)
    assert said == ['PROBLEM flexarm_vision: tool calibration: damaged'] and not watch.closed
    watch.statuses['flexarm_learner: model'] = Heard(OK, 'no model yet')
    reports.step(0.5)                      # the foxglove bridge reports nothing: not awaited
    assert watch.closed and reports.watch is None
    reports.step(0.01)                     # not listening: no new participant either
    assert len(watches) == 1
    again = reports.expect(['flexarm_vision'], 60.0)     # restarted: listens anew
    again.statuses['flexarm_vision: tool calibration'] = Heard(OK, 'correction from file')
    reports.step(0.5)
    assert said[-1] == 'resolved flexarm_vision: tool calibration: OK correction from file'
    assert again.closed and len(watches) == 2
    late = reports.expect(['flexarm_learner'], 0.0)      # never reports: given up
    reports.step(0.5)
    assert late.closed


def test_a_model_line_says_what_a_refreshed_version_was_made_from():
    trained = {'kind': 'greybox', 'metrics': {'samples': 40, 'validation': '5-fold',
                                              'max_error_x': 1e-4, 'max_error_y': 2e-4,
                                              'max_error_phi': 1e-5},
               'provenance': {'dataset': 'A', 'payloads': [0.0]}}
    assert 'refresh' not in model_line('v3', file_summary('3', Path('A-greybox-v3.model'),
                                                          trained))
    refreshed = trained | {'refresh_of': '3', 'refresh_dataset': 'A-refresh', 'corrections': [
        {'samples': 8, 'residual_before': 4.12e-4, 'residual_after': 6.1e-5}]}
    line = model_line('v4', file_summary('4', Path('A-greybox-v4.model'), refreshed))
    assert line.endswith('refresh of v3: 8 samples (A-refresh), median residual 0.412 mm '
                         'before, 0.061 mm after')
    assert 'dataset A, 40 samples at 0 kg' in line


def test_status_says_whether_the_camera_is_calibrated():
    assert calibration_text(None) == 'camera calibration: not heard (no vision node)'
    made = Heard(OK, 'calibrated 2026-11-25T10:00:00 against /ref from 6 poses: c.json')
    assert calibration_text(made) == f'camera calibration: {made.message}'
    assert calibration_text(Heard(ERROR, 'damaged')) == 'camera calibration: PROBLEM: damaged'
    text = status_text(status(camera_calibration=calibration_text(made)), None)
    assert f'\ncamera calibration: {made.message}\n' in text


def test_the_health_line_gives_the_online_bound_and_says_why_it_widened():
    health = {'model_version': '4', 'stale': True, 'stale_residual': 1.5e-4,
              'summary': 'plans of model 4 state 1.0 (position) ... the arm changed',
              'bound_factor': 1.0, 'angle_bound_factor': 2.5, 'bound_goals': 6,
              'bound_misses': 1,
              'regions': [{'name': 'B', 'observations': 6, 'median_position_residual': 3e-3,
                           'max_position_residual': 6e-3, 'stale': True}]}
    text = status_text(status(model_health=health), None)
    assert '1 of 6 measured goals beyond their stated bound' in text
    assert 'plans state 1.0 x (position) and 2.5 x (angle)' in text
    assert 'WARNING: plans of model 4' in text
    calm = health | {'stale': False, 'summary': 'plans of model 4 state 1.3 (position)'}
    assert 'note: plans of model 4' in status_text(status(model_health=calm), None)
