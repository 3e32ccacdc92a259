"""What every flexarm node shares: its ``main()`` (Jazzy style, as in ros2/examples), blocking
work beside its executor, and the end of an action goal.

Executor: every node spins one ``SingleThreadedExecutor``. A ``MultiThreadedExecutor`` rebuilds
its wait set in Python and hands each callback to a thread pool on every wake-up: an idle
learner or compensator spent about half a core in it (benchmarks/footprint.py). Work that
blocks for seconds (a goal's moves, a training) runs in threads of its own (:class:`Offload`),
so the executor keeps serving ``/clock``, cancel requests, parameters and diagnostics
meanwhile. rclpy 7.1.6's ``rclpy.experimental.EventsExecutor`` costs less per message, but its
``spin()`` kept a core busy in an empty node and did not end on SIGTERM: not used.
"""
from __future__ import annotations

import os
import signal
import threading
from collections.abc import Callable, Coroutine
from concurrent.futures import Future as JobFuture
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import wait as wait_jobs
from typing import Any, TypeVar

import rclpy
from rclpy.action.server import ServerGoalHandle
from rclpy.exceptions import InvalidHandle
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from flexarm_core import liveness

T = TypeVar('T')
N = TypeVar('N', bound=Node)


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
# [s, wall; liveness-scaled] for the executor to finish the callback it runs, and for a work
# thread to end its job once the context is shut down (waits poll it every 20 ms; a job that
# computes, a training in its worker process, is not waited for beyond this)
STOP_WAIT = 10.0


def run(make_node: Callable[[], N], args: list[str] | None = None,
        finish: Callable[[SingleThreadedExecutor, N], None] | None = None) -> None:
    """Init rclpy, build the node, spin until SIGINT / SIGTERM / shutdown, then tear down in
    order, on this thread alone: stop the executor, ``finish(executor, node)`` if given (the
    node still up and spinnable on this thread: a recorder writes what already arrived), shut
    the context down (work threads' waits end), let the node end its work threads (its
    ``destroy_node``), destroy it.

    Why not rclpy's own signal handling: on SIGINT it raises KeyboardInterrupt wherever the
    main thread is — inside a callback half-way through creating or destroying an entity (the
    on-demand subscriptions of the vision node and the state publisher change exactly when a
    graph stops and its subscribers leave) — while rclpy's signal thread shuts the context
    down concurrently, and the nodes' work threads still use the node while ``destroy_node``
    finalises it underneath them. Here the executor spins in a thread of its own and a
    signal only wakes this thread (a no-op handler and the wakeup fd: whichever thread the
    kernel hands it to, nothing is interrupted and nothing is killed), so the teardown runs in
    one order whatever the threads were doing. The node exits 0 on SIGINT and SIGTERM, idle
    or mid-goal, except for a crash inside Fast DDS's deletion of the participant soon after
    a peer was killed (docs/operation.md, "How a node ends").
    """
    woken, wake = os.pipe()
    os.set_blocking(wake, False)
    signal.set_wakeup_fd(wake)
    for sig in STOP_SIGNALS:
        signal.signal(sig, _asked_to_stop)
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = make_node()
    except BaseException:
        rclpy.try_shutdown()
        raise
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spin = Spin(executor, lambda: os.write(wake, b'\0'))
    try:
        os.read(woken, 1)       # a signal, or the spin ended by itself
    finally:
        _tear_down(node, executor, spin, finish)
    if spin.error is not None:
        raise spin.error


def _tear_down(node: N, executor: SingleThreadedExecutor, spin: Spin,
               finish: Callable[[SingleThreadedExecutor, N], None] | None) -> None:
    """:func:`run`'s teardown, in its order."""
    if not spin.stop(liveness.limit(STOP_WAIT)):
        # a callback that does not end: destroying the node under it would crash; the
        # process exit frees what it holds
        node.get_logger().error(f'a callback still ran {liveness.limit(STOP_WAIT):g} s after '
                                'the stop was asked for: exiting without destroying the node')
        rclpy.try_shutdown()
        return
    try:
        if finish is not None and spin.error is None:
            finish(executor, node)
    finally:
        executor.shutdown(timeout_sec=0.0)   # drops its wait set (it holds entities in use)
        rclpy.try_shutdown()
        node.destroy_node()


def _asked_to_stop(signum: int, frame: Any) -> None:
    """Nothing: the signal's byte on the wakeup fd is what ends :func:`run`'s wait."""


class Spin:
    """The executor spinning in a thread of its own until :meth:`stop` (or the context's
    shutdown, or a callback's exception, which it keeps in :attr:`error`); ``ended()`` is
    called when it ends. The executor must have its node(s) already; it may be shut down only
    once the spin has ended (:meth:`stop`)."""

    def __init__(self, executor: Executor, ended: Callable[[], object]) -> None:
        self._executor = executor
        self._stopped = threading.Event()
        # stop()'s wake-up: a callback of its own, so the spin-once running returns
        self._stop_guard = executor.get_nodes()[0].create_guard_condition(lambda: None)
        self._ended = ended
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._spin, name='spin', daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        """Run ready callbacks one at a time until stopped: rclpy's public ``spin_once``,
        whose wait ends at :meth:`stop` because the stop triggers a guard condition with a
        callback. Not ``spin_until_future_complete``: Jazzy's adds a done callback to the
        future at every wake-up (ros2/rclpy#1374), and a future pending for the node's life
        grew by ~140 bytes a wake-up: 50 MB an hour of arm time for a measuring vision node at
        x10. Not a future per wait either: rclpy restarts its callback generator whenever the
        wait condition changes, and the first ready task ran again and again."""
        executor = self._executor
        try:
            while executor.context.ok() and not self._stopped.is_set():
                executor.spin_once()
        except ExternalShutdownException:
            pass
        except BaseException as exc:   # noqa: BLE001 - re-raised by the main thread
            self.error = exc
        finally:
            self._ended()

    def stop(self, timeout: float) -> bool:
        """End the spin after the callback it runs; wait up to ``timeout`` s for it. Whether
        it ended (then, and only then, the executor may be shut down)."""
        self._stopped.set()
        self._stop_guard.trigger()
        self._thread.join(timeout)
        return not self._thread.is_alive()


class Offload:
    """Blocking callbacks of a node run in ``threads`` threads of their own: :meth:`wrap` makes
    one a coroutine function, which rclpy awaits, so the executor goes on meanwhile. An action's
    execute callback runs as a task of its own; a service or subscription callback holds its
    callback group while it awaits: give it a group of its own.

    More calls than threads wait for a free one, in order: one thread makes one at a time.
    When a call ends the node's executor is woken, so the awaiting callback ends at once.
    Once the executor has stopped nothing awaits a call any more: from :meth:`shutdown` on, a
    call's error is logged when it ends (one that met the node destroyed under it, rclpy's
    ``InvalidHandle``, is the expected end of a job that outlived ``shutdown``'s wait), not
    printed by the garbage collector as a future's "exception was never retrieved".
    """

    def __init__(self, node: Node, threads: int) -> None:
        self._node = node
        self._pool = ThreadPoolExecutor(threads, thread_name_prefix=node.get_name())
        self._jobs: set[JobFuture] = set()
        self._awaited: set[Future] = set()    # calls' results a callback still awaits

    def wrap(self, call: Callable[..., T]) -> Callable[..., Coroutine[Any, Any, T]]:
        """``call`` as a coroutine function that runs it in the pool: its result, or its
        exception re-raised."""
        async def apart(*args: Any) -> T:
            ended: Future = Future()

            def hand_over(job: JobFuture) -> None:
                error = job.exception()
                if error is None:
                    ended.set_result(job.result())
                else:
                    ended.set_exception(error)
                executor = self._node.executor
                if executor is not None:
                    executor.wake()

            job = self._pool.submit(call, *args)
            self._jobs.add(job)
            self._awaited.add(ended)
            job.add_done_callback(self._jobs.discard)
            job.add_done_callback(hand_over)
            try:
                return await ended
            finally:
                self._awaited.discard(ended)
        return apart

    def shutdown(self, timeout: float | None = None) -> bool:
        """Drop the calls that wait for a thread and wait up to ``timeout`` s (default
        :data:`STOP_WAIT`, liveness-scaled) for the running ones to end: the node is destroyed
        after this, and a thread still in a call would use it. Whether all ended."""
        self._pool.shutdown(wait=False, cancel_futures=True)
        awaited, self._awaited = self._awaited, set()
        for ended in awaited:
            ended.add_done_callback(self._log_error)     # now, if it has ended already
        running = list(self._jobs)
        _, pending = wait_jobs(running, liveness.limit(STOP_WAIT) if timeout is None
                               else timeout)
        return not pending

    def _log_error(self, ended: Future) -> None:
        error = ended.exception()       # retrieved: nothing awaits it any more
        if error is not None and not isinstance(error, InvalidHandle):
            self._node.get_logger().error(f'a job that ended during the shutdown failed: '
                                          f'{error!r}')


def finish_goal(handle: ServerGoalHandle, code: int, canceled_code: int) -> None:
    """End an action goal by its result code: 0 succeeds, ``canceled_code`` cancels, any
    other aborts (the control_msgs convention of an error code in the result)."""
    if code == 0:
        handle.succeed()
    elif code == canceled_code:
        handle.canceled()
    else:
        handle.abort()
