"""Who sent a goal (its candidates at acceptance) and when they have all left."""
import os
import subprocess
import sys
from types import SimpleNamespace

from flexarm_core.dds_profile import PROFILES_ENV, localhost_profile, on_this_machine_only
from flexarm_core.goal_sender import (
    GoalSender,
    ProcTable,
    full_name,
    own_participant,
    process_bits,
    send_goal_writers,
    sender_at_acceptance,
    sender_of,
)

HOST = bytes.fromhex('010f78fd')                   # Fast DDS, host id 78fd


def gid(pid: int, host: bytes = HOST, entity: int = 3, vendor: bytes = b'') -> bytes:
    """A Fast DDS endpoint gid: vendor, host id, low 16 bits of the pid, 2 random bytes,
    participant id, entity id."""
    prefix = (vendor or host[:2]) + host[2:4] + (pid & 0xFFFF).to_bytes(2, 'little')
    return prefix + b'\x11\x22' + bytes(4) + entity.to_bytes(4, 'big')


class Table:
    """Processes of a fake machine: pid -> start time."""

    def __init__(self, **running: int) -> None:
        self.running = {int(k[1:]): v for k, v in running.items()}   # p123=start

    def with_bits(self, bits: int) -> frozenset:
        return frozenset((p, s) for p, s in self.running.items() if p & 0xFFFF == bits)

    def alive(self, process) -> bool:
        return self.running.get(process[0]) == process[1]


def test_the_process_bits_are_read_for_fast_dds_on_this_host_only():
    assert process_bits(gid(13620), HOST) == 13620
    assert process_bits(gid(70000), HOST) == 70000 - 65536
    assert process_bits(gid(13620, host=bytes.fromhex('010f1234')), HOST) is None
    assert process_bits(gid(13620, vendor=b'\x01\x10'), HOST) is None   # another DDS


def test_a_sole_client_is_the_sender_and_gone_when_its_process_ends():
    table = Table(p4242=7)
    sender = sender_at_acceptance([(gid(4242), '/raw_client')], gid(1, entity=9), table)
    assert sender.names == ['/raw_client'] and sender.text() == 'goal sent by /raw_client'
    assert sender.by_discovery_only() == []
    writers = [(gid(4242), '/raw_client'), (gid(5000), '/later_client')]
    assert not sender.gone(writers, table.alive)
    del table.running[4242]                              # killed: discovery still lists it
    assert sender.gone(writers, table.alive)
    table.running[4242] = 8                              # the id reused by another process
    assert sender.gone(writers, table.alive)


def test_a_client_is_gone_when_discovery_drops_it():
    table = Table()                                      # its process not visible here
    sender = sender_at_acceptance([(gid(4242), '/raw_client')], gid(1), table)
    assert sender.candidates[0].processes == frozenset()
    assert sender.by_discovery_only() == ['/raw_client']
    assert not sender.gone([(gid(4242), '/raw_client')], table.alive)
    assert sender.gone([(gid(5000), '/other')], table.alive)


def test_a_client_with_another_host_id_is_judged_by_its_process_when_all_run_here():
    """A process started while a network interface was up has another host id in its GUID:
    where the server's transports reach this machine alone, it runs here all the same."""
    table = Table(p4242=7)
    writers = [(gid(4242, host=bytes.fromhex('010f1234')), '/raw_client')]
    anywhere = sender_at_acceptance(writers, gid(1), table)
    here = sender_at_acceptance(writers, gid(1), table, this_machine_only=True)
    assert anywhere.by_discovery_only() == ['/raw_client'] and here.by_discovery_only() == []
    del table.running[4242]                              # killed: discovery still lists it
    assert here.gone(writers, table.alive) and not anywhere.gone(writers, table.alive)
    other_vendor = [(gid(4242, vendor=b'\x01\x10'), '/raw_client')]
    assert sender_at_acceptance(other_vendor, gid(1), table, True).by_discovery_only()


def test_the_localhost_profile_says_every_participant_runs_here(tmp_path):
    assert on_this_machine_only({PROFILES_ENV: localhost_profile()})
    assert not on_this_machine_only({})
    assert not on_this_machine_only({PROFILES_ENV: str(tmp_path / 'site.xml')})


def test_several_candidates_keep_the_goal_while_any_remains():
    table = Table(p10=1, p20=2)
    writers = [(gid(10), '/flexarm_client'), (gid(20), '/raw_client')]
    sender = sender_at_acceptance(writers, gid(1), table)
    assert sender.text() == 'goal sent by one of /flexarm_client, /raw_client'
    del table.running[20]
    assert not sender.gone(writers, table.alive)
    del table.running[10]
    assert sender.gone(writers, table.alive)


def test_without_candidates_a_goal_is_never_judged_abandoned():
    sender = sender_at_acceptance([], gid(1), Table())
    assert sender == GoalSender() and sender.text() == 'sender unknown'
    assert not sender.gone([], lambda process: False)


def test_the_sender_is_read_back_from_a_result():
    assert sender_of('canceled; arm held; goal sent by /raw_client') == '/raw_client'
    assert sender_of('canceled by the server: it outlasted its time limit, 344 s of the arm\'s '
                     'time; arm held; goal sent by one of /a, /b') == 'one of /a, /b'
    assert sender_of('canceled; arm held; sender unknown') == ''


def test_writers_and_names_come_from_the_request_topic_of_the_action():
    asked = []

    class Graph:
        def get_publishers_info_by_topic(self, topic, no_mangle=False):
            asked.append((topic, no_mangle))
            return [SimpleNamespace(endpoint_gid=list(gid(7)), node_name='cli',
                                    node_namespace='/'),
                    SimpleNamespace(endpoint_gid=list(gid(8)), node_name='_NODE_NAME_UNKNOWN_',
                                    node_namespace='/')]

    writers = send_goal_writers(Graph(), '/arm1/move_to_pose')
    assert asked == [('rq/arm1/move_to_pose/_action/send_goalRequest', True)]
    assert writers == [(gid(7), '/cli'), (gid(8), '?')]
    assert full_name('/arm1', 'flexarm_client') == '/arm1/flexarm_client'
    assert own_participant(writers, '/cli', 7) == gid(7)[:12]
    assert own_participant(writers, '/cli', 8) is None


def test_the_proc_table_knows_live_and_ended_processes():
    table = ProcTable()
    me = next(p for p in table.with_bits(os.getpid() & 0xFFFF) if p[0] == os.getpid())
    assert table.alive(me) and not table.alive((me[0], me[1] + 1))
    child = subprocess.Popen([sys.executable, '-c', 'import sys; sys.stdin.read()'],
                             stdin=subprocess.PIPE)
    (process,) = [p for p in table.with_bits(child.pid & 0xFFFF) if p[0] == child.pid]
    assert table.alive(process)
    child.stdin.close()
    child.wait()
    assert not table.alive(process)


def test_a_sender_discovery_had_not_named_at_acceptance_is_named_later():
    writer = gid(4242)
    sender = sender_at_acceptance([(writer, '?')], HOST, Table(p4242=7))
    assert sender.text() == 'goal sent by ?'
    named = sender.named([(writer, '/goal_sender'), (gid(99), '/other')])
    assert named.text() == 'goal sent by /goal_sender'
    assert named.candidates[0].processes == sender.candidates[0].processes
    assert sender.named([(writer, '?')]).text() == 'goal sent by ?'
