"""`flexarm up` starts its graph where `move`, `status` and `collect` of the same shell look:
``--domain-id`` wins, else the exported ROS_DOMAIN_ID, refused with the reason when another
graph or process holds it; a free domain only when none is exported."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import pytest

from flexarm_bringup import domains
from flexarm_bringup.up_domain import (
    EXPORTED,
    FREE,
    GIVEN,
    DomainRefused,
    claim_domain,
    exported,
)
from flexarm_core import liveness
from flexarm_core.graph_locks import LOCK_DIR, RunningGraph, running_graphs
from flexarm_core.paths import RUNS_DIR
from flexarm_recording.results.outcome_text import Exit

UP_S = 60.0        # [s, liveness-scaled] for `flexarm up` to start its node, or to refuse
GONE_S = 30.0      # [s, liveness-scaled] for a stopped `flexarm up` to end


@pytest.fixture
def unreserved() -> Iterator[int]:
    """A domain beyond those that domain_coordinator and the test runs hand out, free."""
    for did in range(domains.MAX_DOMAIN_ID, domains.LAST, -1):
        sock = domains.hold(did)
        if sock is not None:
            sock.close()
            yield did
            return
    pytest.fail('every domain above the coordinated range is reserved')


def graph(did: int, namespace: str = '') -> RunningGraph:
    return RunningGraph(did, namespace, 4242, 0.0, 'sim', '/runs/up-1')


def test_an_exported_domain_is_read_as_rcl_reads_it() -> None:
    assert exported({}) is None
    assert exported({'ROS_DOMAIN_ID': ''}) is None
    assert exported({'ROS_DOMAIN_ID': ' 7 '}) == 7
    for text in ('seven', '-1', '233'):
        with pytest.raises(DomainRefused, match=f"ROS_DOMAIN_ID='{text}' is exported, but a ROS "
                                                'domain is a whole number 0..232'):
            exported({'ROS_DOMAIN_ID': text})


def test_the_option_wins_over_the_exported_domain_and_reserves_it(unreserved: int) -> None:
    claim = claim_domain(unreserved, {'ROS_DOMAIN_ID': '3'}, '', lambda: [graph(unreserved)])
    with claim.reservation:
        assert (claim.domain_id, claim.how) == (unreserved, GIVEN)
        assert domains.hold(unreserved) is None          # reserved while the graph runs


def test_the_exported_domain_is_used_and_reserved(unreserved: int) -> None:
    claim = claim_domain(None, {'ROS_DOMAIN_ID': str(unreserved)}, '', lambda: [])
    with claim.reservation:
        assert (claim.domain_id, claim.how) == (unreserved, EXPORTED)
        assert domains.hold(unreserved) is None


def test_a_free_domain_only_when_none_is_exported() -> None:
    claim = claim_domain(None, {}, '', lambda: [])
    with claim.reservation:
        assert claim.how == FREE and domains.FIRST <= claim.domain_id <= domains.LAST


def test_a_free_domain_is_one_no_process_runs_in() -> None:
    """A process started in a domain (a ``ros2`` tool, another vendor's node) reserves
    nothing: the free-domain search passes over the domain while it runs there."""
    did, sock = domains.first_free()
    sleeper = subprocess.Popen([sys.executable, '-c', 'import sys; sys.stdin.read()'],
                               env={**os.environ, 'ROS_DOMAIN_ID': str(did)},
                               stdin=subprocess.PIPE)
    try:
        sock.close()                      # nobody reserves it now; the process runs in it
        assert did in domains.in_use()
        other, other_sock = domains.first_free()
        other_sock.close()
        assert other != did
    finally:
        sleeper.communicate(timeout=30)
    assert did not in domains.in_use()


def test_the_domains_in_use_are_read_from_the_environments() -> None:
    assert domains.domain_ids([{'A': '1', 'ROS_DOMAIN_ID': '7'},
                               {'ROS_DOMAIN_ID': ''},                # empty: none
                               {'ROS_DOMAIN_ID': ' 9'},              # as rcl reads it
                               {'ROS_DOMAIN_ID': 'x'}, {}]) == {7, 9}


def test_an_exported_domain_that_runs_the_arm_already_is_refused_naming_its_graph(
        unreserved: int) -> None:
    with pytest.raises(DomainRefused, match=(
            f'ROS_DOMAIN_ID={unreserved} \\(exported\\) already runs the flexarm graph of '
            'supervisor pid 4242 with namespace a \\(robot sim, run folder /runs/up-1\\)')):
        claim_domain(None, {'ROS_DOMAIN_ID': str(unreserved)}, '/a',
                     lambda: [graph(unreserved, 'a')])


def test_an_exported_domain_another_process_reserved_is_refused(unreserved: int) -> None:
    with domains.hold(unreserved):
        with pytest.raises(DomainRefused, match=(
                f'reserved by another process of this machine \\(it holds TCP port '
                f'{domains.PORT_BASE + unreserved},.*--domain-id {unreserved} to start there')):
            claim_domain(None, {'ROS_DOMAIN_ID': str(unreserved)}, '', lambda: [])


def test_another_arm_shares_its_exported_domain(unreserved: int) -> None:
    """Its graph holds the domain's reservation: the second arm starts beside it."""
    with domains.hold(unreserved):
        claim = claim_domain(None, {'ROS_DOMAIN_ID': str(unreserved)}, 'b',
                             lambda: [graph(unreserved, 'a')])
    assert (claim.domain_id, claim.how, claim.reservation) == (unreserved, EXPORTED, None)


# Runs the command line of its arguments in this process (the same pid and environment) once
# a line came on stdin.
GATED = 'import os, sys; sys.stdin.readline(); os.execv(sys.argv[1], sys.argv[1:])'


def up(did: int, *args: str, gated: bool = False, env: dict[str, str] | None = None,
       ) -> subprocess.Popen:
    """``ROS_DOMAIN_ID=did flexarm up --only sim ARGS``: one node is enough to see where the
    graph runs (the rest of it would be expected from other hosts). ``gated``: the process
    runs in ``did`` from now on, and starts ``flexarm up`` when a line comes on its stdin."""
    command = ['-m', 'flexarm_cli', 'up', '--only', 'sim', '--name',
               f'exported-{did}-{os.getpid()}', *args]
    return subprocess.Popen(
        [sys.executable, *(('-c', GATED, sys.executable) if gated else ()), *command],
        env={**(env or os.environ), 'ROS_DOMAIN_ID': str(did), 'PYTHONUNBUFFERED': '1'},
        stdin=subprocess.PIPE if gated else subprocess.DEVNULL, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True)


def refusal(did: int) -> str:
    """What a ``flexarm up`` in ``did`` says on stderr, refused (exit 2, nothing started)."""
    process = up(did)
    try:
        out, err = process.communicate(timeout=liveness.limit(UP_S))
    except subprocess.TimeoutExpired:
        process.kill()
        pytest.fail('flexarm up neither refused the domain nor ended')
    assert process.returncode == Exit.USAGE and 'starting' not in out, (out, err)
    return err


@pytest.mark.node
def test_up_runs_in_the_exported_domain_and_a_held_one_is_refused(
        domain_id: int, domain_pool: Any, ros_node: Any, wait_for: Any) -> None:
    err = refusal(domain_id)          # this run reserves the module's domain
    assert (f'flexarm up: ROS_DOMAIN_ID={domain_id} (exported) is reserved by another process '
            'of this machine') in err, err
    first = up(domain_id, '--timeout', str(liveness.limit(UP_S)), gated=True)
    with domain_pool.lent(domain_id):
        first.stdin.write('go\n')
        first.stdin.flush()
        try:
            line = first.stdout.readline()
            assert f' in ROS_DOMAIN_ID={domain_id} (exported); logs in ' in line, (
                line, first.stderr.read() if not line else '')
            wait_for(lambda: 'flexarm_sim' in ros_node.get_node_names(), UP_S,
                     f'the simulator in ROS domain {domain_id}')
            mine = wait_for(lambda: [g for g in running_graphs(LOCK_DIR, RUNS_DIR)
                                     if g.supervisor_pid == first.pid], UP_S, 'its graph lock')
            assert [g.domain_id for g in mine] == [domain_id]
            assert domains.hold(domain_id) is None       # it reserves the domain it runs in
            err = refusal(domain_id)
            assert (f'ROS_DOMAIN_ID={domain_id} (exported) already runs the flexarm graph of '
                    f'supervisor pid {first.pid} (robot sim, run folder ') in err, err
        finally:
            first.send_signal(signal.SIGINT)
            try:
                out, _ = first.communicate(timeout=liveness.limit(GONE_S))
            except subprocess.TimeoutExpired:
                first.kill()
                pytest.fail('flexarm up did not stop on SIGINT')
        assert 'stopped: flexarm_sim (0)' in out, out
    assert first.returncode == Exit.OK


@pytest.mark.node
def test_a_second_shell_without_a_domain_finds_the_graph_up_started(
        domain_id: int, domain_pool: Any, tmp_path: Any) -> None:
    """`flexarm up` in one shell, `flexarm status` in another with no ROS_DOMAIN_ID exported:
    the status is of that graph, and says which domain it found. Both shells see only each
    other's graph lock (their own TMPDIR): other tests' graphs run meanwhile."""
    private = {k: v for k, v in os.environ.items() if k != 'ROS_DOMAIN_ID'}
    private['TMPDIR'] = str(tmp_path)
    first = up(domain_id, '--timeout', str(liveness.limit(UP_S)), gated=True, env=private)
    with domain_pool.lent(domain_id):
        first.stdin.write('go\n')
        first.stdin.flush()
        try:
            line = first.stdout.readline()
            assert f' in ROS_DOMAIN_ID={domain_id}' in line, (line, first.stderr.read())
            second = subprocess.run(
                [sys.executable, '-m', 'flexarm_cli', 'status'], env=private,
                capture_output=True, text=True,
                timeout=liveness.limit(UP_S))
        finally:
            first.send_signal(signal.SIGINT)
            try:
                first.communicate(timeout=liveness.limit(GONE_S))
            except subprocess.TimeoutExpired:
                first.kill()
                pytest.fail('flexarm up did not stop on SIGINT')
    assert (f'using the flexarm graph of this machine in ROS_DOMAIN_ID={domain_id}'
            in second.stderr), second.stderr
    assert f'ROS_DOMAIN_ID={domain_id}' in second.stdout, second.stdout
    assert 'flexarm_sim' in second.stdout, second.stdout
