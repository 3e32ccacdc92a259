"""Health of the simulated controllers on /diagnostics (pure builders)."""
from flexarm_core.health_report import OK, WARN
from flexarm_sim.fake_controller import link_status
from flexarm_sim.sim_node import controller_status


def test_the_simulator_reports_arm_time_factor_and_payload() -> None:
    s = controller_status('flexarm_sim', '', True, 12.3456, 10.0, 3.14159, 5.0)
    assert s.name == 'flexarm_sim: controller' and s.level == OK and s.hardware_id == ''
    assert s.message == 'arm moving, x3.14 real time (set x10), payload 5 kg'
    assert dict(s.values) == {'arm': 'moving', 'sim time [s]': '12.346',
                              'real-time factor': '3.142', 'real-time factor set': '10',
                              'payload [kg]': '5', 'clock': 'publishes /clock'}
    follower = controller_status('flexarm_sim', '', False, 1.0, 10.0, 10.0, 0.0,
                                 'follows the /clock of /arm1/flexarm_sim')
    assert follower.message.endswith('; follows the /clock of /arm1/flexarm_sim')


def test_the_fake_controller_warns_without_an_authenticated_pc() -> None:
    name, where = 'flexarm_fake_controller', '127.0.0.1:47800'
    alone = link_status(name, where, False, False, False)
    assert alone.level == WARN and 'arm held' in alone.message and alone.hardware_id == where
    waiting = link_status(name, where, True, True, False)
    assert waiting.level == WARN and 'AUTH' in waiting.message
    assert dict(waiting.values)['authenticated'] == 'no'
    keyed = link_status(name, where, True, True, True)
    assert keyed.level == OK and keyed.message == 'PC connected, authenticated'
    plain = link_status(name, where, True, False, False)
    assert plain.level == OK and dict(plain.values)['authenticated'] == 'n/a'
