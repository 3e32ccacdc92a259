"""How a node ends on SIGINT and SIGTERM (:func:`flexarm_core.ros.node_main.run`): the signal only
asks for the shutdown; the callback it lands in completes, the context stays up until the
executor has stopped, work threads end before the node is destroyed, and the exit code is 0.

rclpy's own handling raised KeyboardInterrupt inside the running callback and shut the
context down from its signal thread while the executor and the work threads still used the
node.
"""
from __future__ import annotations

import os
import subprocess
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

HERE = Path(__file__).resolve().parent
TIMEOUT = 60.0   # [s] a bound for a hung node; it ends within about a second


@pytest.mark.node
@pytest.mark.parametrize('sig', ['SIGINT', 'SIGTERM'])
def test_a_signal_mid_callback_ends_the_node_in_order(sig: str, domain_id: int,
                                                      tmp_path: Path) -> None:
    report = tmp_path / 'report.txt'
    env = {k: v for k, v in os.environ.items() if k != '_ROS_WHEELS_BOOTSTRAP_COMPLETE'}
    done = subprocess.run([sys.executable, str(HERE / 'signalled_node.py'), sig, str(report)],
                          env=env, capture_output=True, text=True, timeout=TIMEOUT)
    seen = report.read_text(encoding='utf-8').splitlines() if report.exists() else []
    assert done.returncode == 0, (done.returncode, seen, done.stderr[-2000:])
    assert seen == ['callback entered', 'callback completed', 'job ended before destroy',
                    'destroyed'], (seen, done.stderr[-2000:])


def _growth_over_wake_ups(domain_id: int, spin_for: Callable[[Any, threading.Event], Any]
                          ) -> int:
    """Bytes the process holds more after 2000 more timer wake-ups (1 ms) than after the first
    500, with the executor spun by ``spin_for(executor, stop)``."""
    import tracemalloc

    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = rclpy.create_node('spinner', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    ticks, marks = [0], {500: threading.Event(), 2500: threading.Event()}

    def tick() -> None:
        ticks[0] += 1
        if ticks[0] in marks:
            marks[ticks[0]].set()

    node.create_timer(0.001, tick)
    tracemalloc.start()
    stop = threading.Event()
    spinning = threading.Thread(target=spin_for, args=(executor, stop), daemon=True)
    spinning.start()
    try:
        assert marks[500].wait(TIMEOUT), f'{ticks[0]} wake-ups'
        first = tracemalloc.get_traced_memory()[0]
        assert marks[2500].wait(TIMEOUT), f'{ticks[0]} wake-ups'
        return tracemalloc.get_traced_memory()[0] - first
    finally:
        tracemalloc.stop()
        stop.set()
        executor.wake()
        spinning.join(TIMEOUT)
        executor.shutdown(timeout_sec=0.0)
        node.destroy_node()
        rclpy.try_shutdown(context=context)


LEAK = 100_000      # [bytes] over 2000 wake-ups; Jazzy's leak: ~140 bytes each


@pytest.mark.node
def test_a_long_spin_keeps_nothing_per_wake_up(domain_id: int) -> None:
    """A node spins for its whole life: the spin must keep nothing per wake-up, as Jazzy's
    ``spin_until_future_complete`` does (a done callback on its future each time: the nodes'
    memory grew with every message they were woken for). The same measure sees that leak."""
    from flexarm_core.ros.node_main import Spin

    def ours(executor: Any, stop: threading.Event) -> None:
        spin = Spin(executor, lambda: None)
        stop.wait()
        assert spin.stop(TIMEOUT)

    def jazzys(executor: Any, stop: threading.Event) -> None:
        from rclpy.task import Future

        ended = Future()
        threading.Thread(target=lambda: (stop.wait(), ended.set_result(None)),
                         daemon=True).start()
        executor.spin_until_future_complete(ended)

    assert _growth_over_wake_ups(domain_id, ours) < LEAK
    assert _growth_over_wake_ups(domain_id, jazzys) > LEAK


@pytest.mark.node
def test_a_job_failing_after_the_shutdown_is_logged_not_left_to_the_garbage_collector(
        domain_id: int, capfd: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Once the executor has stopped nothing awaits an offloaded call: its error is logged
    when it ends, and one that met the node destroyed under it is the expected end of a job
    that outlived the shutdown's wait. rclpy's future otherwise printed "The following
    exception was never retrieved" whenever the garbage collector freed it, in whatever ran
    then."""
    import gc
    import threading

    import rclpy
    from rclpy.context import Context
    from rclpy.exceptions import InvalidHandle
    from rclpy.executors import SingleThreadedExecutor

    from flexarm_core.ros.node_main import Offload, Spin

    gc.collect()            # what earlier tests of this worker left is theirs, not this test's
    capfd.readouterr()
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = rclpy.create_node('offloading', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    logged: list[str] = []
    monkeypatch.setattr(node, 'get_logger', lambda: SimpleNamespace(error=logged.append))
    work = Offload(node, 2)
    entered, release = threading.Semaphore(0), threading.Event()

    def job(error: Exception) -> None:
        entered.release()
        release.wait(TIMEOUT)
        raise error

    spin = Spin(executor, lambda: None)
    for error in (ValueError('the late failure'), InvalidHandle('node destroyed')):
        executor.create_task(work.wrap(job), error)
    assert all(entered.acquire(timeout=TIMEOUT) for _ in range(2)), 'the jobs did not start'
    assert spin.stop(TIMEOUT)
    executor.shutdown(timeout_sec=0.0)
    assert not work.shutdown(0.0)            # both still run
    release.set()
    assert work.shutdown(TIMEOUT)
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    del executor, spin              # the last holders of the tasks that await the jobs
    gc.collect()
    out, err = capfd.readouterr()
    assert 'never retrieved' not in out + err, out + err
    assert logged == ["a job that ended during the shutdown failed: ValueError('the late "
                      "failure')"]
