"""A node's health as diagnostic_updater reports it, without ROS (the publishing shell is
:mod:`flexarm_core.ros.diagnostics`).

A node reports one :class:`Status` per concern: ``name`` is ``"<node name>: <concern>"``, the
level is diagnostic_msgs/DiagnosticStatus's (OK, WARN degraded, ERROR broken, STALE no
recent data), the message is one short line, and the values are key/value strings with the
unit in the key (``"residual median [mm]"``: diagnostics are read by people, so mm and deg).
``hardware_id`` names the device a status is about (a controller's ``host:port``, the
camera's frame id), "" for the software's own concerns. Each node's builder, next to the
node, states what it reports and its level rules.

Shared pieces: :class:`CommandLog` (what a controller side took and refused, for the
simulator, the fake controller and the bridge) and :class:`RecentWindow` (valid rate and
median/max of the values of the last seconds, for the vision node).
"""
from __future__ import annotations

import math
import statistics
import threading
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

OK, WARN, ERROR, STALE = 0, 1, 2, 3    # diagnostic_msgs/DiagnosticStatus levels
LEVEL_NAMES = {OK: 'OK', WARN: 'WARN', ERROR: 'ERROR', STALE: 'STALE'}

Value = str | int | float | bool


@dataclass(frozen=True)
class Status:
    """One concern of one node: a DiagnosticStatus without ROS."""

    level: int
    name: str
    message: str
    hardware_id: str = ''
    values: tuple[tuple[str, str], ...] = ()


def value_text(value: Value) -> str:
    """A value as the text of a KeyValue: numbers to 6 significant digits, bools yes/no."""
    if isinstance(value, bool):
        return 'yes' if value else 'no'
    if isinstance(value, float):
        return f'{value:.6g}'
    return str(value)


def status(node: str, concern: str, level: int, message: str,
           values: Mapping[str, Value] | None = None, hardware_id: str = '') -> Status:
    """The status named ``"<node>: <concern>"``, its values as text in the given order."""
    if level not in LEVEL_NAMES:
        raise ValueError(f'unknown diagnostic level {level}')
    return Status(level, f'{node}: {concern}', message, hardware_id,
                  tuple((key, value_text(v)) for key, v in (values or {}).items()))


class CommandLog:
    """Joint commands a controller side accepted and rejected, and the last rejection's reason
    (thread-safe: commands come from ROS callbacks and socket threads)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.accepted = 0
        self.rejected = 0
        self.last_reason = ''          # of the last rejection
        self.last_rejected = False     # the latest command was rejected

    def record(self, reason: str | None) -> None:
        """One command: accepted (``reason`` None) or rejected for ``reason``."""
        with self._lock:
            if reason is None:
                self.accepted += 1
            else:
                self.rejected += 1
                self.last_reason = reason
            self.last_rejected = reason is not None

    def status(self, node: str, hardware_id: str = '') -> Status:
        """``<node>: commands``: WARN while the latest command was rejected (the arm is not
        where its sender wants it), else OK."""
        with self._lock:
            values = {'commands accepted': self.accepted, 'commands rejected': self.rejected,
                      'last rejection': self.last_reason}
            if self.last_rejected:
                return status(node, 'commands', WARN, f'last command rejected: '
                              f'{self.last_reason}', values, hardware_id)
        message = f'{self.accepted} accepted' if self.accepted else 'no command yet'
        return status(node, 'commands', OK, message, values, hardware_id)


@dataclass(frozen=True)
class WindowSummary:
    """The entries of a :class:`RecentWindow`: how many, how many valid, and the median and
    maximum of the valid entries' values (NaN without a valid one)."""

    count: int
    valid: int
    median: float
    maximum: float

    @property
    def valid_rate(self) -> float:
        """Fraction of valid entries, NaN for an empty window."""
        return self.valid / self.count if self.count else math.nan


class RecentWindow:
    """Outcomes of the last ``span`` seconds, each valid with a value or invalid; times are
    the caller's (a monotonic clock)."""

    def __init__(self, span: float) -> None:
        if not span > 0:
            raise ValueError(f'window span must be > 0 s, got {span}')
        self.span = span
        self._entries: deque[tuple[float, float | None]] = deque()

    def add(self, t: float, value: float | None) -> None:
        """One outcome at time ``t`` [s]: the value of a valid one, None for an invalid one."""
        self._entries.append((t, value))
        self._forget(t)

    def summary(self, now: float) -> WindowSummary:
        """The entries of the ``span`` seconds up to ``now``."""
        self._forget(now)
        values = [v for _, v in self._entries if v is not None]
        if not values:
            return WindowSummary(len(self._entries), 0, math.nan, math.nan)
        return WindowSummary(len(self._entries), len(values), statistics.median(values),
                             max(values))

    def _forget(self, now: float) -> None:
        while self._entries and self._entries[0][0] < now - self.span:
            self._entries.popleft()
