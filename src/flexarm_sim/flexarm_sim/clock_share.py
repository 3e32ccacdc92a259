"""Which of the simulators of one ROS domain publishes ``/clock`` (pure; the node applies it).

Several arms in one domain run on one clock: one simulator publishes ``/clock``, the others follow
it (:mod:`flexarm_sim.sim_node`). The domain's time must neither stop nor step back when the
publisher goes or comes back, so:

* A follower takes the clock over from the time it has reached when ``/clock`` has been silent
  for ``silence`` wall seconds (the publisher's graph stopped, its process died), or when
  ``/clock`` is behind its own time by more than ``margin`` ticks (the publisher was restarted
  at time 0):
  its time is then the domain's latest.
* Two publishers (two followers took over at once, a publisher starved for longer than the silence,
  a restarted publisher) are resolved by each hearing the other: the one behind by more than
  ``margin`` yields and follows, since following only ever steps time forward; within
  ``margin`` the one whose node name sorts after the other's yields, so both decide alike.

A publisher tells another publisher's ``/clock`` from its own by the time: it remembers the
ticks it published, and keeps them when it yields. Two publishers of the very same ticks are
one clock, until they drift apart.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

OWN, FOLLOW = 'own', 'follow'
ROLES = (OWN, FOLLOW)
REMEMBERED = 64     # own /clock ticks a publisher keeps to tell another publisher's from its own


def yields(own_tick: int, own_name: str, other_tick: int, other_name: str,
           margin: int) -> bool:
    """Whether a publisher of ``/clock`` at ``own_tick`` gives it up to another publisher that
    published ``other_tick`` (module docstring)."""
    if abs(other_tick - own_tick) <= margin:
        return other_name < own_name
    return other_tick > own_tick


@dataclass
class ClockShare:
    """One simulator's part in its domain's clock: its role, whom it follows, whom it took the
    clock over from. Times: ``now`` in wall seconds (monotonic), ticks of the simulator."""

    role: str
    name: str                   # this simulator's fully qualified node name
    silence: float              # [s, wall] of silent /clock before a follower takes over
    margin: int                 # [ticks]
    started: float              # [s, wall] when following began: silent since then
    publisher: str = ''             # following: the publisher's node name, once discovered
    took_over: tuple[str, int] | None = None   # (from whom, at which tick)
    _heard: float | None = None                 # [s, wall] the last /clock, following
    _published: deque[int] = field(default_factory=lambda: deque(maxlen=REMEMBERED))

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise ValueError(f'clock_source must be one of {ROLES}, not {self.role!r}')

    def published(self, tick: int) -> None:
        """A publisher published ``/clock`` at ``tick``."""
        self._published.append(tick)

    def is_own(self, tick: int) -> bool:
        """Whether a ``/clock`` at ``tick`` is one this simulator published: also after it
        yielded, when its last ticks may still arrive behind the other publisher's (taken for the
        publisher's clock going back, they would take the clock over again)."""
        return tick in self._published

    def heard(self, now: float, tick: int, own_tick: int) -> bool:
        """A follower heard ``/clock`` at ``tick``: whether it takes the clock over (the
        clock is behind its own time, ``own_tick``)."""
        self._heard = now
        return own_tick - tick > self.margin

    def silent(self, now: float) -> bool:
        """Whether a follower's ``/clock`` has been silent for ``silence`` s."""
        return self.role == FOLLOW and now - (self._heard or self.started) > self.silence

    def take_over(self, tick: int) -> None:
        self.role, self.took_over = OWN, (self.publisher, tick)
        self._published.clear()

    def follow(self, publisher: str, now: float) -> None:
        """Give the clock up to ``publisher`` (a publisher that yields)."""
        self.role, self.publisher, self.started, self._heard = FOLLOW, publisher, now, None

    def text(self, dt: float) -> str:
        """The role in words, for the simulator's diagnostics (``dt``: s per tick)."""
        if self.role == FOLLOW:
            return f'follows the /clock of {self.publisher or "another arm"}'
        if self.took_over is None:
            return 'publishes /clock'
        publisher, tick = self.took_over
        return (f'publishes /clock, taken over at {tick * dt:.3f} s from '
                f'{publisher or "another arm"}')
