"""What ``flexarm up`` hears of its own graph while it supervises it: the arm's
``/diagnostics`` and active model (:class:`GraphWatch`), and each ERROR of a node's first
reports, at start and after a restart (:class:`FirstReports`)."""
from __future__ import annotations

import time
from collections.abc import Callable, Iterable

from diagnostic_msgs.msg import DiagnosticArray

from flexarm_bringup.graph_status import (
    LATCHED,
    ErrorLog,
    diagnosed,
    heard,
    reporting_nodes,
)
from flexarm_bringup.status_text import Heard
from flexarm_core import topics
from flexarm_msgs.msg import ModelInfo


class GraphWatch:
    """The arm's ``/diagnostics`` statuses and the compensator's active model, heard by a
    node of its own (one context; spun by the caller, so signals stay Python's)."""

    def __init__(self, domain_id: int, namespace: str = '') -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self._context = Context()
        rclpy.init(context=self._context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        ns = namespace.strip('/')
        self._node = rclpy.create_node('flexarm_up_watch', context=self._context,
                                       namespace=f'/{ns}' if ns else '')
        self.statuses: dict[str, Heard] = {}
        self.active_model: ModelInfo | None = None
        self._node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS,
                                       lambda m: self.statuses.update(heard(m, ns)), 10)
        self._node.create_subscription(ModelInfo, topics.ACTIVE_MODEL,
                                       lambda m: setattr(self, 'active_model', m), LATCHED)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)

    def spin(self, seconds: float, until: Callable[[], bool] = lambda: False) -> None:
        """Take what comes for ``seconds``, or until ``until()`` holds."""
        end = time.monotonic() + seconds
        while not until() and time.monotonic() < end:
            self._executor.spin_once(timeout_sec=min(0.1, max(0.0, end - time.monotonic())))

    def forget(self, nodes: Iterable[str]) -> None:
        """Drop what ``nodes`` said so far (restarted: what they say now counts)."""
        for name in [n for n in self.statuses if n.split(': ', 1)[0] in set(nodes)]:
            del self.statuses[name]

    def close(self) -> None:
        import rclpy

        self._executor.shutdown()
        self._node.destroy_node()
        rclpy.try_shutdown(context=self._context)


class FirstReports:
    """``flexarm up``'s ear on ``/diagnostics``: open while nodes' first reports are due (after
    the graph is ready, after a node's restart), each ERROR said as it comes (:class:`ErrorLog`).

    A node reads its files (tool calibration, model record) when it starts, so its first
    reports say what is damaged; a participant held for ``up``'s whole life would instead leave
    its shared memory behind whenever ``up`` is killed with SIGKILL.
    """

    def __init__(self, listen: Callable[[], GraphWatch], say: Callable[[str], None]) -> None:
        self._listen, self._say = listen, say
        self.watch: GraphWatch | None = None
        self._due: dict[str, float] = {}       # node: until when its first report is awaited
        self._errors = ErrorLog()

    def expect(self, nodes: Iterable[str], within: float) -> GraphWatch:
        """Listen until each of ``nodes`` has reported, for ``within`` seconds at most."""
        nodes = sorted(diagnosed(frozenset(nodes)))
        if self.watch is None:
            self.watch = self._listen()
        self.watch.forget(nodes)
        self._due.update(dict.fromkeys(nodes, time.monotonic() + within))
        return self.watch

    def step(self, seconds: float) -> None:
        """Listen (or wait) ``seconds``; say what is new; stop listening once nothing is due."""
        if self.watch is None:
            time.sleep(seconds)
            return
        self.watch.spin(seconds)
        for line in self._errors.update(self.watch.statuses):
            self._say(line)
        heard_from, now = reporting_nodes(self.watch.statuses), time.monotonic()
        self._due = {n: t for n, t in self._due.items() if n not in heard_from and t > now}
        if not self._due:
            self.close()

    def close(self) -> None:
        if self.watch is not None:
            self.watch.close()
            self.watch = None
