"""The header stamps of a recorded graph, stream by stream (pure): is its time one time?

A topic with several publishers interleaves their stamps in arrival order, and each publisher
stamps with its own data's time (an image's capture lags the clock), so order is checked per
stream: per transform child on ``/tf``, per node on ``/diagnostics``, per topic elsewhere.

And no stamp is ahead of the graph's time when its message was sent (:func:`beyond_sent`): a
wall-clock stamp in a simulated graph, or one from the future. The graph's time then is not
the newest ``/clock`` before the message: the simulator steps a clock period of ticks per
wake-up and publishes ``/clock`` with the last of them (flexarm_sim.sim_node), so the burst's
messages leave up to a period (0.2 s of sim time at 5x, 4 s at 100x) ahead of the newest
``/clock``. Nor is it the last ``/clock`` of the bag: a recorder keeps what it can take (keep
last of a queue, a bounded drain when stopped, what the transport delivered), so its last
``/clock`` may be older than messages it recorded after it. What bounds it is any ``/clock``
published after the message was (sim time never steps back): the first one the bag holds with
a later publish time (the publisher's source timestamp, wall clock, one clock for every
process of the machine), or for the messages after the bag's last one, the graph's time once
the recording had ended. This holds however late or lossy the recording, and it still fails a
stamp of wall time (decades ahead) or beyond the simulator's own time.
"""
from __future__ import annotations

from bisect import bisect_left
from collections.abc import Iterable, Iterator, Sequence
from typing import Any

from flexarm_core.ros.stamps import to_ns
from flexarm_core.topics import CLOCK, DIAGNOSTICS

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


def beyond_sent(messages: Sequence[tuple[str, Any, int]], final_ns: int,
                clock: str = CLOCK) -> dict[Stream, int]:
    """The streams with a header stamp ahead of the graph's time when the message was sent,
    each with its largest lead [ns] (module docstring); empty when none is.

    ``messages``: (topic, decoded message, publish time [ns, wall]) of a recording, ``clock``
    among them; ``final_ns``: the stamp of a ``/clock`` published after the recording ended,
    the bound of what was published after the last recorded ``/clock``."""
    clocks = sorted((published, to_ns(msg.clock)) for topic, msg, published in messages
                    if topic == clock)
    published_at = [published for published, _ in clocks]
    lead: dict[Stream, int] = {}
    for topic, msg, published in messages:
        after = bisect_left(published_at, published)
        bound = clocks[after][1] if after < len(clocks) else final_ns
        for stream, ns in header_stamps(topic, msg):
            if ns > bound:
                lead[stream] = max(lead.get(stream, 0), ns - bound)
    return lead
