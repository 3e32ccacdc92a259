"""Subscriptions whose messages are taken, not called back: no message wakes the node's
executor (a wake-up costs a node more than the message; ``/joint_states`` at 10x real time is
1000 a wall second, ``/clock`` 25). The owner takes what arrived when it looks."""
from __future__ import annotations

from typing import Any

from rclpy.callback_groups import CallbackGroup
from rclpy.exceptions import InvalidHandle
from rclpy.subscription import Subscription


class Taken(CallbackGroup):
    """The callback group of subscriptions that the executor never runs: their owner takes
    what arrived when it looks (:func:`take`)."""

    def can_execute(self, entity: Any) -> bool:
        return False

    def beginning_execution(self, entity: Any) -> bool:
        return False

    def ending_execution(self, entity: Any) -> None:
        return None


def take(subscription: Subscription) -> Any:
    """The oldest message waiting in a subscription of a :class:`Taken` group (raw bytes for
    a raw subscription); None if none, or if the node shut down and destroyed it."""
    try:
        with subscription.handle:
            taken = subscription.handle.take_message(subscription.msg_type, subscription.raw)
    except InvalidHandle:
        return None
    return None if taken is None else taken[0]
