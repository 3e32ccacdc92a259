"""The time of a node's data: the stamp for what a node without a clock of its own says.

Nodes that skip the ``/clock`` subscription (each ``/clock`` is a wake-up of the node) cannot
read sim time from their clock, and their wall clock mixed into a sim-time graph steps back
and forth by decades. They stamp what they say with the newest stamp of the data they handled
instead, so it is in the graph's time (sim or wall, whichever the data are in) and never steps
back. Before the first data the stamp is 0: ROS's "no time yet", what a sim-time clock reads
before ``/clock``; for tf2, a static transform holds at every time whatever its stamp.
"""
from __future__ import annotations

from builtin_interfaces.msg import Time

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
