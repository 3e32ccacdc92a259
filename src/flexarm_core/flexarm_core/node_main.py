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

from collections.abc import Callable, Coroutine
from concurrent.futures import Future as JobFuture
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

import rclpy
from rclpy.action.server import ServerGoalHandle
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.task import Future

T = TypeVar('T')


def run(make_node: Callable[[], Node], args: list[str] | None = None) -> None:
    """Init rclpy, build the node, spin until Ctrl-C / SIGTERM / shutdown, clean up.

    A RuntimeError raised by a subscription take while SIGINT shuts the context down (an
    rclpy race) ends the node like the interrupt it is, with exit code 0.
    """
    rclpy.init(args=args)
    node = None
    try:
        node = make_node()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


class Offload:
    """Blocking callbacks of a node run in ``threads`` threads of their own: :meth:`wrap` makes
    one a coroutine function, which rclpy awaits, so the executor goes on meanwhile. An action's
    execute callback runs as a task of its own; a service or subscription callback holds its
    callback group while it awaits: give it a group of its own.

    More calls than threads wait for a free one, in order: one thread makes one at a time.
    When a call ends the node's executor is woken, so the awaiting callback ends at once.
    """

    def __init__(self, node: Node, threads: int) -> None:
        self._node = node
        self._pool = ThreadPoolExecutor(threads, thread_name_prefix=node.get_name())

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

            self._pool.submit(call, *args).add_done_callback(hand_over)
            return await ended
        return apart

    def shutdown(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)


def finish_goal(handle: ServerGoalHandle, code: int, canceled_code: int) -> None:
    """End an action goal by its result code: 0 succeeds, ``canceled_code`` cancels, any
    other aborts (the control_msgs convention of an error code in the result)."""
    if code == 0:
        handle.succeed()
    elif code == canceled_code:
        handle.canceled()
    else:
        handle.abort()
