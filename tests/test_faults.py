"""Fault injection at node level: what a hostile but fair site does to the graph.

The module's tests share its ROS domain (conftest.py), one graph at a time, with bounded waits.
The tests that train share one simulator and learner (:class:`LearnerGraph`), the one that
kills the learner last; every other test starts the nodes it needs, in a domain without them.
"""
import contextlib
import json
import os
import signal
import socket
import time
import uuid
from pathlib import Path

import psutil
import pytest
import rclpy
from rclpy.context import Context

from flexarm_bridge import tcp_link
from flexarm_control.ros.client import SERVER_SILENCE
from flexarm_core import liveness, processes
from flexarm_core.dds_shm import owned_shm
from flexarm_test_support import link_attacks

pytestmark = [pytest.mark.node, pytest.mark.duration(100)]


def children(pid: int) -> set[int]:
    """PIDs whose parent is ``pid`` (zombies excluded)."""
    return {child.pid for child in psutil.Process(pid).children() if processes.alive(child.pid)}


class LearnerGraph:
    """Simulator and learner with a dataset ``good`` of 20 samples (folders of their own),
    started by ``module_launch`` for a test that trains (:func:`learner`) and kept for the
    next one while the learner lives; stopped (and reaped) before any other test of the module
    runs (:func:`_one_graph_at_a_time`)."""

    def __init__(self, launcher, folders: pytest.TempPathFactory) -> None:
        self._launcher, self._folders = launcher, folders
        self.node = None

    def start(self, write_dataset) -> None:
        if self.node is not None and self.node.returncode is None:
            return
        self.stop()
        folder = self._folders.mktemp('learner')
        data, models = folder / 'data', folder / 'models'
        data.mkdir()
        write_dataset(data / 'good.jsonl', count=20)
        self._launcher('flexarm_sim', real_time_factor=10.0)
        self.node = self._launcher('flexarm_learner', data_directory=str(data),
                                   model_directory=str(models))
        self.data, self.models = data, models

    def stop(self) -> None:
        self._launcher.stop_all()
        self.node = None


@pytest.fixture(scope='module')
def learner_graph(module_launch, tmp_path_factory) -> LearnerGraph:
    return LearnerGraph(module_launch, tmp_path_factory)


@pytest.fixture(autouse=True)
def _one_graph_at_a_time(request):
    """A test that does not train runs without the learner graph: two simulators must not
    share the domain, and the graph refusals need it empty of flexarm nodes."""
    if 'learner' not in request.fixturenames:
        request.getfixturevalue('learner_graph').stop()


@pytest.fixture
def learner(learner_graph, write_dataset, ready_client):
    """The shared simulator and learner (:class:`LearnerGraph`): the learner's process, a
    client, and the learner's data and model folders."""
    learner_graph.start(write_dataset)
    return (learner_graph.node, ready_client(compensator=False), learner_graph.data,
            learner_graph.models)


def test_training_reports_damaged_dataset_records(learner, write_dataset):
    _, client, data, _ = learner
    name = f'damaged-{uuid.uuid4().hex[:8]}'     # a dataset of this test alone
    write_dataset(data / f'{name}.jsonl', count=20)
    path = Path(client.train('rbf', dataset=name, timeout=60).model_path)
    assert path.exists()
    dataset = path.parent.parent / 'data' / f'{name}.jsonl'
    with open(dataset, 'ab') as f:
        f.write(b'{"crc32": "00000000", "sample": {}}\n{"torn')      # a bad and a torn line
    trained = client.train('rbf', dataset=name, timeout=60)
    assert trained.success, trained.message
    assert '2 damaged record(s)' in trained.message and 'lines 22, 23' in trained.message


def test_a_learner_killed_after_training_leaves_no_worker(learner, wait_for):
    node, client, _, _ = learner
    trained = client.train('rbf', dataset='good', timeout=60)
    assert trained.success, trained.message
    pid = node.process.pid
    workers = children(pid)
    assert workers, 'the training worker process was not found'
    node.killed_shm += owned_shm(pid)             # removed when the graph stops
    os.kill(pid, signal.SIGKILL)                  # the learner only, not its process group
    wait_for(lambda: not any(processes.alive(w) for w in workers), 5.0,
             f'the learner\'s children {sorted(workers)} to die with it')


def test_a_restarted_learner_keeps_the_declared_payload(learner, learner_graph, module_launch,
                                                        wait_for):
    """The arm keeps its tool when the learner dies: the learner that comes back announces
    the payload last declared, not its configured 0 kg, and the simulator keeps carrying it."""
    node, client, data, models = learner
    client.set_payload(3.5)
    wait_for(lambda: client.node_parameter('flexarm_sim', 'plant.payload') == 3.5, 10.0,
             'the simulator to take the tool')
    node.killed_shm += owned_shm(node.process.pid)     # removed when the graph stops
    node.signal(signal.SIGKILL)
    learner_graph.node = module_launch('flexarm_learner', data_directory=str(data),
                                       model_directory=str(models))

    def declared() -> float | None:
        with contextlib.suppress(TimeoutError, RuntimeError):   # until it is discovered
            return client.node_parameter('flexarm_learner', 'payload', timeout=2.0)
        return None

    wait_for(lambda: declared() == 3.5, 20.0, 'the restarted learner to declare 3.5 kg')
    assert client.node_parameter('flexarm_sim', 'plant.payload') == 3.5
    client.set_payload(0.0)
    assert json.loads((models / 'payload.json').read_text()) == {'payload': 0.0}


def test_a_graph_refuses_a_domain_that_runs_a_node_of_its_names(domain_id, tmp_path):
    from flexarm_bringup.supervisor import Graph

    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    other = rclpy.create_node('flexarm_sim', context=context)     # another graph's simulator
    graph = Graph(domain_id, tmp_path / 'run')
    try:
        with pytest.raises(RuntimeError, match=f'domain {domain_id} already runs flexarm_sim'):
            graph.start()
        assert all(node.process is None for node in graph.nodes.values())   # nothing started
    finally:
        other.destroy_node()
        rclpy.try_shutdown(context=context)



def test_a_graph_refuses_at_once_a_domain_another_graph_of_this_machine_holds(domain_id,
                                                                              tmp_path):
    from flexarm_bringup.supervisor import Graph, lock_domain

    held = lock_domain(domain_id)                  # as a running `flexarm up` holds it
    graph = Graph(domain_id, tmp_path / 'run')
    try:
        started = time.monotonic()
        with pytest.raises(RuntimeError, match=f'in use by another flexarm graph on this '
                                               f'machine \\(supervisor pid {os.getpid()}\\)'):
            graph.start()
        assert time.monotonic() - started < liveness.limit(1.0)   # no discovery wait
        assert all(node.process is None for node in graph.nodes.values())
        started = time.monotonic()
        graph.stop()                                  # nothing to stop: no waiting either
        assert time.monotonic() - started < liveness.limit(1.0)
    finally:
        os.close(held)
    os.close(lock_domain(domain_id))                # released: free for the next graph

@pytest.fixture
def moving_graph(launch, ready_client):
    """Simulator (real time: a long move takes seconds) and compensator; their processes and
    a client."""
    sim = launch('flexarm_sim', real_time_factor=1.0)
    compensator = launch('flexarm_compensator')
    return sim, compensator, ready_client(learner=False)


def kill_mid_move(client, victim) -> tuple[dict, float]:
    """Start a long RIGID move, SIGKILL ``victim`` (a node process) once the arm moves; the
    goal's ``result`` or ``error``, and the seconds from the kill until it ended."""
    import math
    import threading

    phases, outcome = [], {}

    def move() -> None:
        try:
            outcome['result'] = client.move_to(1.0, -0.5, math.radians(-100), mode='rigid',
                                               timeout=120,
                                               feedback=lambda fb: phases.append(fb.phase))
        except Exception as exc:   # the outcome is what the tests look at
            outcome['error'] = exc

    thread = threading.Thread(target=move)
    thread.start()
    deadline = time.monotonic() + 20
    while 'moving' not in phases and time.monotonic() < deadline:
        time.sleep(0.05)
    assert 'moving' in phases, 'the goal did not start moving'
    victim.signal(signal.SIGKILL)
    killed = time.monotonic()
    thread.join(timeout=liveness.limit(15.0))
    assert not thread.is_alive(), 'the client still waits after the kill'
    return outcome, time.monotonic() - killed


def test_a_client_notices_its_server_die_mid_goal(moving_graph):
    from flexarm_control.ros.client import ServerLost

    _, compensator, client = moving_graph
    outcome, seconds = kill_mid_move(client, compensator)
    assert isinstance(outcome.get('error'), ServerLost), outcome
    assert 'flexarm_compensator' in str(outcome['error'])
    assert seconds < liveness.limit(SERVER_SILENCE + 3.0)


def test_a_collection_client_notices_the_learner_die_and_no_sample_is_lost(launch, tmp_path,
                                                                          ready_client):
    import threading

    from flexarm_control.ros.client import ServerLost
    from flexarm_deflection.dataset import load_dataset

    launch('flexarm_sim', real_time_factor=10.0)
    launch('flexarm_vision')
    learner = launch('flexarm_learner', data_directory=str(tmp_path / 'data'))
    client = ready_client(compensator=False)
    done, outcome = [], {}

    def collect() -> None:
        try:
            client.collect(40, dataset='d', timeout=600,
                           feedback=lambda fb: done.append(fb.k - fb.skipped))
        except Exception as exc:   # the outcome is what the test looks at
            outcome['error'] = exc

    thread = threading.Thread(target=collect)
    thread.start()
    deadline = time.monotonic() + 60
    while (not done or done[-1] < 3) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert done and done[-1] >= 3, 'the collection did not get going'
    learner.signal(signal.SIGKILL)
    killed = time.monotonic()
    thread.join(timeout=liveness.limit(15.0))
    assert not thread.is_alive(), 'the client still waits for a dead learner'
    assert isinstance(outcome.get('error'), ServerLost), outcome
    assert 'flexarm_learner' in str(outcome['error'])
    assert time.monotonic() - killed < liveness.limit(SERVER_SILENCE + 3.0)
    dataset = load_dataset(tmp_path / 'data' / 'd.jsonl')
    assert dataset.skipped_lines == []
    assert len(dataset.samples) >= done[-1]        # every sample reported is on disk

def test_a_second_pc_is_refused_at_once_and_never_queued(launch, domain_id, wait_for):
    from flexarm_bridge import controller_protocol as proto

    port = 47000 + 2 * domain_id
    launch('flexarm_fake_controller', robot='bridge', port=port)

    def connect() -> tuple[socket.socket, proto.Decoder]:
        return link_attacks.connect(port), proto.Decoder()

    def first_frame(conn: socket.socket, decoder: proto.Decoder) -> proto.Frame | None:
        """The first frame from the controller, or None if it closed the connection."""
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:
            data = conn.recv(4096)
            if not data:
                return None
            frames, _ = decoder.feed(data)
            if frames:
                return frames[0]
        pytest.fail('no frame from the controller within 5 s')

    first, first_decoder = connect()
    assert first_frame(first, first_decoder).type == proto.HELLO
    second, second_decoder = connect()
    refusal = first_frame(second, second_decoder)
    assert refusal.type == proto.ERROR and refusal.fields['code'] == proto.E_BUSY
    second.settimeout(2.0)
    assert second.recv(4096) == b''              # closed after the refusal
    second.close()
    first.close()
    started = time.monotonic()                   # served as soon as the first has gone
    while True:                                  # (the controller notices within ~0.1 s)
        third, third_decoder = connect()
        frame = first_frame(third, third_decoder)
        third.close()
        if frame is not None and frame.type == proto.HELLO:
            break
        assert frame is not None and frame.fields['code'] == proto.E_BUSY
        assert time.monotonic() - started < liveness.limit(2.0), 'locked out after the PC left'
        time.sleep(0.05)


class RawPC:
    """A PC speaking the controller protocol by hand: with the site key or without."""

    def __init__(self, port: int, auth=None) -> None:
        from flexarm_bridge import controller_protocol as proto
        deadline = time.monotonic() + 20
        while True:
            try:
                self.conn = tcp_link.connect('127.0.0.1', port, timeout=0.1)
                break
            except OSError:
                assert time.monotonic() < deadline, 'the fake controller does not listen'
                time.sleep(0.2)
        self.auth, self.decoder = auth, proto.Decoder(auth)
        self.frames, self.errors, self.seq, self.closed = [], [], 0, False

    def send(self, frame_type: int, tamper: bool = False, **fields) -> int:
        from flexarm_bridge import controller_protocol as proto
        self.seq += 1
        key = None if self.auth is None else proto.frame_key(self.auth, frame_type, True)
        data = bytearray(proto.encode(frame_type, self.seq, key, **fields))
        if tamper:
            data[12] ^= 0x01                     # a bit of the payload
        self.conn.sendall(bytes(data))
        return self.seq

    def listen(self, seconds: float, until=lambda: False) -> None:
        """Collect frames for ``seconds``, or until ``until()`` holds (sending HEARTBEAT every
        0.2 s once authenticated)."""
        from flexarm_bridge import controller_protocol as proto
        end, beat = time.monotonic() + seconds, 0.0
        while time.monotonic() < end and not self.closed and not until():
            if self.auth is not None and self.auth.established and time.monotonic() > beat:
                self.send(proto.HEARTBEAT, time=time.monotonic())
                beat = time.monotonic() + 0.2
            try:
                data = self.conn.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                data = b''
            if not data:
                self.closed = True
            frames, errors = self.decoder.feed(data)
            self.frames += frames
            self.errors += errors

    def of_type(self, frame_type: int) -> list:
        return [f for f in self.frames if f.type == frame_type]


def test_only_a_pc_with_the_site_key_commands_the_arm(launch, domain_id, tmp_path):
    from flexarm_bridge import controller_protocol as proto
    from flexarm_bridge.link_auth import PC, LinkAuth, load_key, make_key

    port = 47000 + 2 * domain_id
    key_file = make_key(tmp_path / 'site.key')
    controller = launch('flexarm_fake_controller', robot='bridge', port=port,
                        link_key_file=str(key_file))
    stranger = RawPC(port)                       # no key: a plain command, then silence
    stranger.listen(liveness.limit(5.0), until=lambda: any('no link key' in e
                                                           for e in stranger.errors))
    assert stranger.frames == [] and any('no link key' in e for e in stranger.errors)
    stranger.send(proto.JOINT_COMMAND, positions=[0.3, 0.7, 0.0, 0.0])
    stranger.listen(3.0)
    assert stranger.closed, 'the controller keeps a PC that never authenticates'
    assert stranger.frames == []                 # it never read a frame of the controller

    pc = RawPC(port, LinkAuth(load_key(key_file), PC))
    pc.listen(liveness.limit(5.0), until=lambda: pc.of_type(proto.HELLO))
    assert pc.of_type(proto.HELLO)                 # taken by its decoder: answer it
    pc.send(proto.AUTH, **pc.auth.answer())
    pc.listen(liveness.limit(5.0), until=lambda: pc.of_type(proto.JOINT_STATE))
    state = pc.of_type(proto.JOINT_STATE)[-1]
    assert not state.fields['status'] & proto.STATUS_MOVING    # the stranger moved nothing
    start = state.fields['positions']
    target = [start[0] + 0.02, *start[1:]]
    logged = len(controller.log_path.read_text())
    valid = pc.send(proto.JOINT_COMMAND, positions=target)
    tampered = pc.send(proto.JOINT_COMMAND, tamper=True, positions=target)
    pc.conn.sendall(proto.encode(proto.JOINT_COMMAND, valid, pc.auth.send_key,
                                 positions=[start[0] - 0.2, *start[1:]]))    # replayed seq

    def all_handled() -> bool:
        """The valid command acknowledged and the arm on its way, the other two refused (the
        controller logs a refused frame where it would have acknowledged it)."""
        log = controller.log_path.read_text()[logged:]
        return (valid in [a.fields['acked'] for a in pc.of_type(proto.ACK)]
                and pc.of_type(proto.JOINT_STATE)[-1].fields['positions'][0] > start[0] + 0.005
                and 'tag mismatch' in log and 'replayed' in log)

    pc.listen(liveness.limit(5.0), until=all_handled)
    pc.conn.close()
    assert [(a.fields['acked'], a.fields['code']) for a in pc.of_type(proto.ACK)] == [
        (valid, proto.OK)]
    assert tampered not in [a.fields['acked'] for a in pc.of_type(proto.ACK)]
    last = pc.of_type(proto.JOINT_STATE)[-1].fields['positions']
    assert last[0] > start[0] + 0.005            # moving to the valid target only
    log = controller.log_path.read_text()
    assert 'tag mismatch' in log and 'replayed' in log and 'requires authentication' in log


def test_the_link_leaves_loopback_only_with_a_key(launch, domain_id, wait_for):
    port = 47000 + 2 * domain_id
    controller = launch('flexarm_fake_controller', robot='bridge', host='0.0.0.0', port=port)
    bridge = launch('flexarm_bridge', robot='bridge', host='192.0.2.1', port=port)   # TEST-NET
    wait_for(lambda: controller.returncode is not None and bridge.returncode is not None,
             30.0, 'both to refuse')
    assert controller.returncode == bridge.returncode == 1
    assert 'refusing to listen' in controller.log_path.read_text()
    assert 'refusing to connect' in bridge.log_path.read_text()


def test_a_goal_fails_at_once_when_the_controller_dies_mid_move(moving_graph):
    from flexarm_motion.ros.arm_interface import JOINT_SILENCE
    from flexarm_msgs.action import MoveToPose

    sim, _, client = moving_graph
    outcome, seconds = kill_mid_move(client, sim)
    result = outcome['result']
    assert result.error_code == MoveToPose.Result.CONTROLLER_TIMEOUT
    assert 'stopped publishing /joint_states' in result.error_string, result.error_string
    assert seconds < liveness.limit(JOINT_SILENCE + 3.0)   # the silence, not the travel timeout
