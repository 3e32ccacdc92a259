"""Health of the bridge's controller link on /diagnostics (pure builder)."""
from flexarm_bridge.bridge_node import link_status
from flexarm_core.health_report import ERROR, OK, WARN

WHERE = '10.0.0.7:47800'


def test_the_link_is_ok_linked_warns_reconnecting_and_errs_down() -> None:
    up = link_status('flexarm_bridge', WHERE, True, 0.0, 'closed by the controller', 3, 5.0)
    assert up.level == OK and up.hardware_id == WHERE and up.message == f'linked to {WHERE}'
    assert dict(up.values)['reconnects'] == '2' and dict(up.values)['down for [s]'] == '0'
    again = link_status('flexarm_bridge', WHERE, False, 1.2, 'no frame for 1.0 s', 3, 5.0)
    assert again.level == WARN and again.message == (
        f'reconnecting to {WHERE} (no frame for 1.0 s)')
    down = link_status('flexarm_bridge', WHERE, False, 7.4, 'unreachable (refused)', 3, 5.0)
    assert down.level == ERROR and down.message == 'link down for 7 s: unreachable (refused)'
    never = link_status('flexarm_bridge', WHERE, False, 6.0, '', 0, 5.0)
    assert never.level == ERROR and 'no joint state from the controller' in never.message
    assert dict(never.values)['reconnects'] == '0'
