"""``/diagnostics`` for a node (rclpy side of :mod:`flexarm_core.health_report`).

Every flexarm node publishes its statuses as one ``diagnostic_msgs/DiagnosticArray`` on
``/diagnostics`` once a second of wall-clock time, also when the graph runs on the
simulator's faster clock (the timer is on the steady clock), so rqt_robot_monitor and
Foxglove's diagnostics panel see the graph's health at a steady rate, and at once to a
subscriber that has just matched (``flexarm status`` answers without waiting up to a period
for each node). Stamps come from the
node's clock (sim time under ``use_sim_time``) unless the node gives its own: a node that skips
``/clock`` gives the graph's time (:class:`flexarm_core.ros.stamps.GraphTime`). ``/diagnostics``
is global: a node in a namespace (one arm of several) names its statuses
``<namespace>/<node>: <concern>``.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable

from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.callback_groups import CallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks, QoSPublisherMatchedInfo
from rclpy.node import Node

from flexarm_core import topics
from flexarm_core.health_report import ERROR, Status, status

PERIOD = 1.0                    # [s, wall] between two reports


def diagnostic_array(statuses: Iterable[Status], stamp: TimeMsg, namespace: str = ''
                     ) -> DiagnosticArray:
    """The message of ``statuses``, stamped ``stamp``, their names in ``namespace``."""
    prefix = f'{namespace.strip("/")}/' if namespace.strip('/') else ''
    msg = DiagnosticArray(status=[DiagnosticStatus(
        level=bytes([s.level]), name=prefix + s.name, message=s.message, hardware_id=s.hardware_id,
        values=[KeyValue(key=key, value=value) for key, value in s.values])
        for s in statuses])
    msg.header.stamp = stamp
    return msg


class DiagnosticsPublisher:
    """Publishes ``statuses()`` on ``/diagnostics`` every ``period`` seconds of wall time.

    A builder that raises is itself reported (ERROR ``<node>: diagnostics``) and logged;
    it never ends the node.
    """

    def __init__(self, node: Node, statuses: Callable[[], Iterable[Status]],
                 period: float = PERIOD, stamp: Callable[[], TimeMsg] | None = None,
                 callback_group: CallbackGroup | None = None) -> None:
        self._node = node
        self._statuses = statuses
        self._stamp = stamp or (lambda: node.get_clock().now().to_msg())
        self._pub = node.create_publisher(
            DiagnosticArray, topics.DIAGNOSTICS, 10, callback_group=callback_group,
            event_callbacks=PublisherEventCallbacks(matched=self._on_matched))
        self._timer = node.create_timer(period, self.publish, callback_group=callback_group,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _on_matched(self, info: QoSPublisherMatchedInfo) -> None:
        if info.current_count_change > 0:      # a new subscriber: it hears the statuses now
            self.publish()

    def publish(self) -> None:
        """Publish the node's statuses now."""
        try:
            statuses = list(self._statuses())
        except Exception as exc:   # a broken report is news itself, never a crash
            reason = f'{type(exc).__name__}: {exc}'
            self._node.get_logger().error(f'diagnostics report failed: {reason}',
                                          throttle_duration_sec=60.0)
            statuses = [status(self._node.get_name(), 'diagnostics', ERROR,
                               f'report failed: {reason}')]
        self._pub.publish(diagnostic_array(statuses, self._stamp(),
                                           self._node.get_namespace()))
