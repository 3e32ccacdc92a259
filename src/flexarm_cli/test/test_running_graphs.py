"""`flexarm ps` and `flexarm down` see exactly the graphs whose supervisor holds its domain
lock, pick the one meant or say why they cannot, and stop it as Ctrl-C would. A graph here is a
plain process that locks a file as the supervisor does (no ROS)."""
from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

import flexarm_cli as cli
from flexarm_bringup.running_graphs import (
    AmbiguousGraph,
    NoSuchGraph,
    graph_table,
    select,
    stop,
)
from flexarm_cli import graph as graph_commands
from flexarm_core import graph_locks
from flexarm_core.graph_locks import (
    RECORD,
    RunningGraph,
    SeveralGraphs,
    graph_domain,
    lock_holders,
    lock_name,
    lock_site,
    lock_text,
    parse_lock_name,
    running_graphs,
)
from flexarm_core.parent_death import terminate_with_parent

# Locks LOCK_FILE as supervisor._lock_domain does, says so, then waits; SIGINT (Python's
# default: KeyboardInterrupt) ends it, unless IGNORE_SIGINT.
HOLDER = '''
import fcntl, os, signal, sys
# as flexarm's own main(): its handler, whatever SIGINT disposition the test run inherited
# (a run started in the background of a non-interactive shell ignores SIGINT)
signal.signal(signal.SIGINT, signal.SIG_IGN if sys.argv[2] == "ignore"
              else signal.default_int_handler)
fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT, 0o666)
fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
os.pwrite(fd, str(os.getpid()).encode(), 0)
print("locked", flush=True)
signal.pause()
'''


@pytest.fixture
def dirs(tmp_path: Path) -> tuple[Path, Path]:
    (tmp_path / 'locks').mkdir()
    (tmp_path / 'runs').mkdir()
    return tmp_path / 'locks', tmp_path / 'runs'


@pytest.fixture
def holders() -> Iterator[list[subprocess.Popen]]:
    started: list[subprocess.Popen] = []
    yield started
    for process in started:
        process.kill()
        process.wait()


def hold(started: list[subprocess.Popen], lock_dir: Path, runs_dir: Path, domain_id: int,
         namespace: str = '', on_sigint: str = 'end') -> subprocess.Popen:
    """A graph stand-in: a process holding the lock of ``domain_id``/``namespace``, and its
    record in a run folder."""
    process = subprocess.Popen(
        [sys.executable, '-c', HOLDER, str(lock_dir / lock_name(domain_id, namespace)),
         on_sigint], stdout=subprocess.PIPE, text=True, preexec_fn=terminate_with_parent)
    started.append(process)
    assert process.stdout.readline().strip() == 'locked'
    run = runs_dir / f'run-{domain_id}-{namespace.replace("/", "-")}'
    run.mkdir()
    (run / RECORD).write_text(json.dumps({
        'supervisor_pid': process.pid, 'domain_id': domain_id, 'robot': 'bridge',
        'namespace': namespace, 'remote': [], 'nodes': {'flexarm_bridge': {'pid': 1}}}))
    return process


def test_lock_names_carry_domain_and_namespace():
    for domain, ns in ((7, ''), (7, 'arm1'), (12, 'site/arm2')):
        assert parse_lock_name(lock_name(domain, ns)) == (domain, ns)
    assert lock_name(12, 'site/arm2') == '12-site.arm2.lock'
    assert parse_lock_name('notes.txt') is None and parse_lock_name('x-1.lock') is None


def test_proc_locks_give_the_holders_of_each_flock_only():
    text = ('1: FLOCK  ADVISORY  WRITE 27728 00:1b:4984466 0 EOF\n'
            '1: -> FLOCK  ADVISORY  WRITE 31000 00:1b:4984466 0 EOF\n'
            '2: POSIX  ADVISORY  WRITE 512 fd:01:77 0 EOF\n'
            '3: FLOCK  ADVISORY  WRITE 4242 fd:01:99 0 EOF\n'
            '4: FLOCK  ADVISORY  READ 5151 fd:01:98 0 EOF\n'       # a shared lock, two holders
            '4: FLOCK  ADVISORY  READ 5252 fd:01:98 0 EOF\n')
    assert lock_holders(text) == [((0, 0x1b, 4984466), 27728), ((0xfd, 1, 99), 4242),
                                  ((0xfd, 1, 98), 5151), ((0xfd, 1, 98), 5252)]


def test_ps_lists_the_graphs_whose_lock_is_held_with_their_record(dirs, holders):
    lock_dir, runs_dir = dirs
    first = hold(holders, lock_dir, runs_dir, 7)
    arm = hold(holders, lock_dir, runs_dir, 7, 'arm2')
    (lock_dir / lock_name(9)).write_text('999999')      # a graph that ended: no lock held
    graphs = running_graphs(lock_dir, runs_dir)
    assert [(g.domain_id, g.namespace, g.supervisor_pid) for g in graphs] == [
        (7, '', first.pid), (7, 'arm2', arm.pid)]
    assert graphs[0].robot == 'bridge' and graphs[0].nodes == ('flexarm_bridge',)
    assert graphs[0].run_dir == str(runs_dir / 'run-7-')
    table = graph_table(graphs).splitlines()
    assert table[0].split() == ['DOMAIN', 'NAMESPACE', 'PID', 'STARTED', 'ROBOT', 'RUN']
    assert table[2].split()[:3] == ['7', 'arm2', str(arm.pid)]


def test_a_graph_without_record_is_listed_with_what_its_lock_says(dirs, holders):
    lock_dir, runs_dir = dirs
    process = hold(holders, lock_dir, runs_dir, 5)
    (runs_dir / 'run-5-' / RECORD).unlink()
    [graph] = running_graphs(lock_dir, runs_dir)
    assert (graph.domain_id, graph.supervisor_pid, graph.robot) == (5, process.pid, '?')


def _graph(domain_id: int, namespace: str = '') -> RunningGraph:
    return RunningGraph(domain_id, namespace, 100 + domain_id, 0.0)


def test_down_takes_the_only_graph_or_the_one_named():
    one, arm1, arm2 = _graph(3), _graph(7, 'arm1'), _graph(7, 'arm2')
    assert select([one]) == one
    assert select([one, arm1, arm2], domain_id=3) == one
    assert select([one, arm1, arm2], 7, 'arm2') == arm2
    assert select([one, arm1, arm2], namespace='arm1') == arm1
    assert select([one, arm1], namespace='') == one


def test_down_refuses_to_guess_among_several_graphs():
    with pytest.raises(AmbiguousGraph, match='pass --domain-id') as caught:
        select([_graph(3), _graph(4)])
    assert '3 ' in str(caught.value) and '4 ' in str(caught.value)    # the table of both
    with pytest.raises(AmbiguousGraph, match='in ROS domain 7: pass --namespace'):
        select([_graph(7, 'arm1'), _graph(7, 'arm2')], domain_id=7)


def test_down_says_when_no_graph_matches():
    with pytest.raises(NoSuchGraph, match='^no flexarm graph runs on this machine$'):
        select([])
    with pytest.raises(NoSuchGraph, match='no flexarm graph in ROS domain 5 runs') as caught:
        select([_graph(3)], domain_id=5)
    assert 'running:' in str(caught.value)
    with pytest.raises(NoSuchGraph, match='in ROS domain 7 with namespace arm3'):
        select([_graph(7, 'arm1')], 7, 'arm3')


def test_stop_interrupts_the_supervisor_and_waits_until_it_has_ended(dirs, holders):
    lock_dir, runs_dir = dirs
    process = hold(holders, lock_dir, runs_dir, 7)
    [graph] = running_graphs(lock_dir, runs_dir)
    assert stop(graph, timeout=10.0)
    assert process.wait(timeout=0) != 0              # ended by SIGINT (KeyboardInterrupt)
    assert running_graphs(lock_dir, runs_dir) == []


def test_stop_says_so_when_the_supervisor_does_not_end_in_time(dirs, holders):
    lock_dir, runs_dir = dirs
    process = hold(holders, lock_dir, runs_dir, 7, on_sigint='ignore')
    [graph] = running_graphs(lock_dir, runs_dir)
    assert not stop(graph, timeout=0.2)
    assert process.poll() is None


def test_flexarm_down_stops_the_only_graph_and_ps_shows_none(dirs, holders, monkeypatch,
                                                             capsys):
    lock_dir, runs_dir = dirs
    monkeypatch.setattr(graph_locks, 'LOCK_DIR', lock_dir)
    monkeypatch.setattr(graph_commands, 'RUNS_DIR', runs_dir)
    hold(holders, lock_dir, runs_dir, 7, 'arm1')
    hold(holders, lock_dir, runs_dir, 8)
    assert cli.main(['down']) == 2
    assert 'pass --domain-id' in capsys.readouterr().err
    assert cli.main(['down', '--domain-id', '9']) == 3
    assert cli.main(['down', '--domain-id', '7', '--quiet']) == 0
    assert 'stopped the graph in ROS domain 7 with namespace arm1' in capsys.readouterr().out
    assert cli.main(['ps', '--json']) == 0
    result = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert [g['domain_id'] for g in result['graphs']] == [8]


def test_a_client_finds_the_one_graph_of_this_machine_and_asks_when_there_are_several(
        dirs, holders):
    """A second shell without ROS_DOMAIN_ID: the graph `flexarm up` started in the first free
    domain, said; two graphs: which one, by --domain-id; an exported domain: rcl's."""
    lock_dir, runs_dir = dirs
    assert graph_domain('', {}, lock_dir, runs_dir) == (None, '')      # none: rcl's default
    first = hold(holders, lock_dir, runs_dir, 3)
    domain, note = graph_domain('', {}, lock_dir, runs_dir)
    assert domain == 3 and 'ROS_DOMAIN_ID=3' in note and str(first.pid) in note
    assert graph_domain('', {'ROS_DOMAIN_ID': '9'}, lock_dir, runs_dir) == (None, '')
    hold(holders, lock_dir, runs_dir, 5)
    with pytest.raises(SeveralGraphs, match=r'ROS domains 3, 5: pass --domain-id'):
        graph_domain('', {}, lock_dir, runs_dir)
    hold(holders, lock_dir, runs_dir, 5, 'arm2')                        # one arm of it
    assert graph_domain('arm2', {}, lock_dir, runs_dir)[0] == 5


def test_a_graph_s_lock_says_its_site_where_its_record_lies(dirs, holders, tmp_path):
    """A graph started in a site folder keeps its run record there: the lock file names the
    site, so a shell that does not know the site finds the graph's record and its site."""
    lock_dir, runs_dir = dirs
    site = tmp_path / 'site'
    (site / 'runs').mkdir(parents=True)
    process = hold(holders, lock_dir, site / 'runs', 4)
    lock = lock_dir / lock_name(4)
    lock.write_text(lock_text(process.pid, site))
    [graph] = running_graphs(lock_dir, runs_dir)
    assert (graph.site, graph.robot) == (str(site), 'bridge')
    assert lock_site(lock) == str(site) and lock_text(7, None) == '7\n'
