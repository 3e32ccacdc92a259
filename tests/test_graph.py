"""Node-level: the whole graph comes up, is supervised, and shuts down leaving nothing behind."""
import os
import signal

import pytest

from flexarm_bringup.orchestration.launcher import owned_shm
from flexarm_bringup.orchestration.supervisor import Graph
from flexarm_core import liveness

pytestmark = [pytest.mark.node, pytest.mark.duration(20)]


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_graph_up_supervised_and_down_without_orphans(domain_id, tmp_path):
    reports: list[str] = []
    graph = Graph(domain_id, tmp_path / 'run', optional=('flexarm_recorder',),
                  parameters={'flexarm_sim': {'real_time_factor': 5.0},
                              'flexarm_recorder': {'bag_directory': str(tmp_path / 'bags'),
                                                   'bag_name': 'graph'},
                              'flexarm_learner': {'data_directory': str(tmp_path / 'data')}},
                  report=reports.append)
    graph.start()
    try:
        graph.wait_ready(liveness.limit(60.0))
        assert set(graph.nodes) == {'flexarm_sim', 'flexarm_arm_owner', 'flexarm_vision',
                                    'flexarm_learner',
                                    'flexarm_compensator', 'flexarm_state_publisher',
                                    'flexarm_scene', 'flexarm_recorder'}
        assert all((tmp_path / 'run' / f'{name}.log').exists() for name in graph.nodes)

        vision = graph.nodes['flexarm_vision']          # restart: true in graph.yaml
        old_pid = vision.process.pid
        left = owned_shm(old_pid)                       # what SIGKILL leaves behind
        assert left, 'the vision node owns no shared memory to leave behind'
        vision.signal(signal.SIGKILL)
        vision.process.wait(timeout=10)
        assert graph.check() == ['flexarm_vision']
        assert any('flexarm_vision exited with code -9' in r for r in reports)
        assert vision.restarts == 1 and vision.process.pid != old_pid
        graph.wait_ready(liveness.limit(30.0))           # /tip_pose is back

        assert [p.name for p in left if p.exists() and "port" not in p.name] == []   # restart
        sim = graph.nodes['flexarm_sim']                 # restart: false
        left += owned_shm(sim.process.pid)
        sim.signal(signal.SIGKILL)
        sim.process.wait(timeout=10)
        assert graph.check() == ['flexarm_sim'] and sim.returncode == -9
        assert graph.check() == []                       # reported once, stays down
        assert all(n.returncode is None for name, n in graph.nodes.items()
                   if name != 'flexarm_sim')
    finally:
        pids = [n.process.pid for n in graph.nodes.values()]
        codes = graph.stop(timeout=10.0)
    assert not any(alive(pid) for pid in pids)
    clean = {name: code for name, code in codes.items() if name != 'flexarm_sim'}
    assert all(code == 0 for code in clean.values()), clean       # SIGINT: clean exits
    # The killed nodes' segments are gone. Their ports are shared by every participant of the
    # machine listening on them (other tests' too), and stay while one was in use at removal.
    assert [p.name for p in left if p.exists() and 'port' not in p.name] == []
    assert (tmp_path / 'bags' / 'graph' / 'metadata.yaml').exists()
