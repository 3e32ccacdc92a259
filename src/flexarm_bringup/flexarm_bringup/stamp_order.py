"""The header stamps of a recorded graph, stream by stream (pure): is its time one time?

A topic with several publishers interleaves their stamps in arrival order, and each publisher
stamps with its own data's time (an image's capture lags the clock), so order is checked per
stream: per transform child on ``/tf``, per node on ``/diagnostics``, per topic elsewhere.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Any

from flexarm_core.stamps import to_ns
from flexarm_core.topics import DIAGNOSTICS

Stream = tuple[str, str]        # (topic, source)


def header_stamps(topic: str, msg: Any) -> Iterator[tuple[Stream, int]]:
    """(stream, stamp [ns]) of each header of a decoded message: the transforms of a
    TFMessage, the markers of a MarkerArray, else the message's own header (if any); a
    ``/diagnostics`` message is its first status's node's."""
    if hasattr(msg, 'transforms'):
        for t in msg.transforms:
            yield (topic, t.child_frame_id), to_ns(t.header.stamp)
    elif hasattr(msg, 'markers'):
        for m in msg.markers:
            yield (topic, ''), to_ns(m.header.stamp)
    elif hasattr(msg, 'header'):
        node = msg.status[0].name.split(':')[0] if topic == DIAGNOSTICS and msg.status else ''
        yield (topic, node), to_ns(msg.header.stamp)


def backwards_steps(stamps: Iterable[tuple[Stream, int]]) -> dict[Stream, int]:
    """How often each stream's stamp went back (0 for every stream seen in order)."""
    last: dict[Stream, int] = {}
    steps: dict[Stream, int] = {}
    for stream, ns in stamps:
        steps[stream] = steps.get(stream, 0) + (ns < last.get(stream, ns))
        last[stream] = ns
    return steps
