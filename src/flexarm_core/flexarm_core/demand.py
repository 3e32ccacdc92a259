"""Whether anyone consumes a node's outputs (pure): inputs taken only while they are wanted.

A node that turns one stream into another — the vision node images into ``/tip_pose``, the
state publisher ``/joint_states`` into ``/tf`` — subscribes to its inputs only while one of
its outputs has a subscriber, as image_pipeline's lazy nodes do: an input nobody consumes the
result of is neither received, parsed nor computed on, and the producer upstream (the
simulator renders images only while they have a subscriber) stops as well. The node shell
feeds :meth:`Demand.update` from its publishers' *matched* events (rmw: a subscription came or
went), so nothing polls the graph.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any


class Demand:
    """Tells ``on_change(True)`` when the first of the watched outputs gains a subscriber and
    ``on_change(False)`` when the last one loses its last."""

    def __init__(self, on_change: Callable[[bool], None]) -> None:
        self._on_change = on_change
        self._counts: dict[str, int] = {}

    @property
    def wanted(self) -> bool:
        return any(self._counts.values())

    def update(self, output: str, subscribers: int) -> None:
        """``output`` has ``subscribers`` matched subscriptions now."""
        before = self.wanted
        self._counts[output] = subscribers
        if self.wanted != before:
            self._on_change(self.wanted)


def on_matched(output: str, *demands: Demand) -> Callable[[Any], None]:
    """The matched-event callback of the publisher of ``output`` (rclpy's
    ``PublisherEventCallbacks(matched=...)``): feeds its subscriber count to ``demands``."""
    def matched(info: Any) -> None:
        for demand in demands:
            demand.update(output, info.current_count)
    return matched
