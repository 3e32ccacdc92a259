"""The time of a node's data, and the graph's time: stamps for a node without ``/clock``.

Nodes that skip the ``/clock`` subscription (each ``/clock`` is a wake-up of the node) cannot
read sim time from their clock, and their wall clock mixed into a sim-time graph steps back
and forth by decades. What they derive from data keeps the data's stamp; what is about now (a
node's health on ``/diagnostics``, the scene's markers) is stamped with the graph's time
(:class:`GraphTime`): the newest ``/clock``, taken without waking the node, in a simulated
graph, or the node's own clock (a real arm's wall time). :class:`DataTime` keeps the
newest stamp seen (0 before any: ROS's "no time yet", what a sim-time clock reads before
``/clock``; for tf2, a static transform holds at every time whatever its stamp).
"""
from __future__ import annotations

from builtin_interfaces.msg import Time
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription
from rosgraph_msgs.msg import Clock

from flexarm_core import topics
from flexarm_core.ros.node_params import declare
from flexarm_core.ros.taken import Taken, take

NS = 1_000_000_000
CDR_STAMP = slice(4, 12)    # serialized: 4-byte CDR encapsulation, then the stamp (8 bytes)


def to_ns(stamp: Time) -> int:
    """A stamp in nanoseconds."""
    return stamp.sec * NS + stamp.nanosec


def raw_stamp_ns(raw: bytes) -> int:
    """The stamp [ns] of a serialized message whose first field is a stamp or a Header
    (rosgraph_msgs/Clock, sensor_msgs/JointState, ...), read without deserializing it."""
    order = 'little' if raw[1] & 1 else 'big'       # encapsulation kind: CDR_LE is 0x0001
    stamp = raw[CDR_STAMP]
    return (int.from_bytes(stamp[:4], order, signed=True) * NS
            + int.from_bytes(stamp[4:], order))


class DataTime:
    """The newest stamp seen of a node's data; 0 until the first."""

    def __init__(self) -> None:
        self.ns = 0

    def saw(self, stamp: Time) -> None:
        """Data stamped ``stamp`` was handled; one older than the newest changes nothing."""
        self.saw_ns(to_ns(stamp))

    def saw_ns(self, ns: int) -> None:
        """:meth:`saw` of a stamp in nanoseconds."""
        self.ns = max(self.ns, ns)

    def stamp(self) -> Time:
        """The newest stamp seen, as a message field."""
        sec, nanosec = divmod(self.ns, NS)
        return Time(sec=sec, nanosec=nanosec)


class GraphTime:
    """The graph's time now for a node that does not follow ``/clock``. The node's ``sim_clock``
    parameter (declared here from config/clock.yaml; config/graph.yaml's robot entry sets it,
    as ``use_sim_time`` for the nodes that follow ``/clock``) says which: true, the newest
    ``/clock`` (at most one ``/clock`` period old; 0 until one is heard); false, the node's own
    clock (wall time)."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._clock: Subscription | None = None
        if declare(node, 'sim_clock', 'config/clock.yaml', read_only=True):
            self._clock = node.create_subscription(Clock, topics.CLOCK, lambda _: None,
                                                   QoSProfile(depth=1),
                                                   callback_group=Taken(), raw=True)
        self._newest = DataTime()

    def stamp(self) -> Time:
        if self._clock is None:
            return self._node.get_clock().now().to_msg()
        while (raw := take(self._clock)) is not None:
            self._newest.saw_ns(raw_stamp_ns(raw))
        return self._newest.stamp()
