"""Node health for /diagnostics: the pure statuses and windows, their publisher, and the
learner's and compensator's builders."""
import math
import threading

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

from flexarm_core import topics
from flexarm_core.health_report import (
    ERROR,
    OK,
    STALE,
    WARN,
    CommandLog,
    RecentWindow,
    status,
    value_text,
)
from flexarm_core.ros.diagnostics import DiagnosticsPublisher, diagnostic_array


def test_a_status_is_named_after_node_and_concern_with_text_values() -> None:
    s = status('flexarm_vision', 'measurements', WARN, '40 % valid',
               {'valid rate [%]': 40.0, 'images': 50, 'camera_info refused': False,
                'last invalid reason': 'too dark'}, hardware_id='tip_camera')
    assert s.name == 'flexarm_vision: measurements' and s.level == WARN
    assert s.hardware_id == 'tip_camera' and s.message == '40 % valid'
    assert s.values == (('valid rate [%]', '40'), ('images', '50'),
                        ('camera_info refused', 'no'), ('last invalid reason', 'too dark'))
    assert status('n', 'c', OK, 'fine').values == () and status('n', 'c', OK, '').hardware_id == ''
    with pytest.raises(ValueError, match='level 7'):
        status('n', 'c', 7, 'no such level')


def test_values_read_as_text() -> None:
    assert value_text(0.0271234567) == '0.0271235' and value_text(math.nan) == 'nan'
    assert value_text(True) == 'yes' and value_text(3) == '3' and value_text('x') == 'x'


def test_the_command_log_warns_while_the_latest_command_was_rejected() -> None:
    log = CommandLog()
    first = log.status('flexarm_sim')
    assert first.level == OK and first.message == 'no command yet'
    assert first.name == 'flexarm_sim: commands'
    log.record(None)
    log.record('joint2 = 0.9 m beyond its limit')
    warned = log.status('flexarm_bridge', 'localhost:47800')
    assert warned.level == WARN and 'joint2 = 0.9 m' in warned.message
    assert warned.hardware_id == 'localhost:47800'
    assert dict(warned.values) == {'commands accepted': '1', 'commands rejected': '1',
                                   'last rejection': 'joint2 = 0.9 m beyond its limit'}
    log.record(None)
    again = log.status('flexarm_sim')
    assert again.level == OK and again.message == '2 accepted'
    assert dict(again.values)['last rejection'] == 'joint2 = 0.9 m beyond its limit'


def test_the_command_log_counts_commands_from_several_threads() -> None:
    log = CommandLog()

    def send(reason: str | None) -> None:
        for _ in range(2000):
            log.record(reason)

    threads = [threading.Thread(target=send, args=(r,)) for r in (None, None, 'limits')]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert (log.accepted, log.rejected) == (4000, 2000)


def test_the_window_keeps_the_last_span_of_seconds() -> None:
    window = RecentWindow(10.0)
    empty = window.summary(0.0)
    assert (empty.count, empty.valid) == (0, 0) and math.isnan(empty.valid_rate)
    for t, value in [(0.0, 5.0), (1.0, None), (2.0, 1.0), (3.0, 2.0), (4.0, None)]:
        window.add(t, value)
    s = window.summary(4.0)
    assert (s.count, s.valid, s.median, s.maximum) == (5, 3, 2.0, 5.0)
    assert s.valid_rate == pytest.approx(0.6)
    s = window.summary(10.5)          # the entry at 0 s is older than 10 s now
    assert (s.count, s.valid, s.median, s.maximum) == (4, 2, 1.5, 2.0)
    s = window.summary(13.5)          # only the invalid one at 4 s is left
    assert (s.count, s.valid) == (1, 0) and math.isnan(s.median) and s.valid_rate == 0.0
    assert window.summary(20.0).count == 0
    with pytest.raises(ValueError):
        RecentWindow(0.0)


def test_statuses_become_one_diagnostic_array() -> None:
    stamp = DiagnosticArray().header.stamp
    stamp.sec = 12
    msg = diagnostic_array([
        status('flexarm_learner', 'model', ERROR, 'no model announced', {'version': ''}),
        status('flexarm_vision', 'measurements', STALE, 'no image', hardware_id='cam')], stamp)
    assert msg.header.stamp.sec == 12 and len(msg.status) == 2
    first, second = msg.status
    assert first.level == DiagnosticStatus.ERROR and second.level == DiagnosticStatus.STALE
    assert (first.name, first.message, first.hardware_id) == (
        'flexarm_learner: model', 'no model announced', '')
    assert [(v.key, v.value) for v in first.values] == [('version', '')]
    assert second.hardware_id == 'cam' and not second.values


@pytest.mark.node
@pytest.mark.parametrize('ros_node', [{'use_sim_time': True}], indirect=True)
def test_diagnostics_come_every_wall_second_also_on_a_stopped_sim_clock(ros_node,
                                                                         wait_for) -> None:
    """No /clock runs: a sim-time timer would never fire. A failing report is reported."""
    received: list[DiagnosticArray] = []
    ros_node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, received.append, 10)
    reports = iter([[status(ros_node.get_name(), 'test', OK, 'fine')]])

    def statuses() -> list:
        return next(reports)    # StopIteration from the second report on

    DiagnosticsPublisher(ros_node, statuses, period=0.2)
    wait_for(lambda: len(received) >= 3, 10.0, 'three /diagnostics messages')
    first, second = received[0].status[0], received[1].status[0]
    assert (first.name, first.level, first.message) == (
        'test_client: test', DiagnosticStatus.OK, 'fine')
    assert second.name == 'test_client: diagnostics' and second.level == DiagnosticStatus.ERROR
    assert second.message.startswith('report failed: StopIteration')
    assert received[0].header.stamp.sec == 0      # the node's (sim) clock: no /clock yet
