"""This machine's processes, read by psutil without tripping over one that ends meanwhile.

A process can end between the listing of the processes and the reading of its facts: psutil
then raises ``NoSuchProcess`` (``ZombieProcess``, one of them, for an ended process its parent
has not reaped yet), and ``AccessDenied`` for a process not ours to read. So every fact here is
read inside a ``try`` and reads as "gone"; a zombie has ended too.

Two facts psutil gives only at a cost, read from ``/proc`` here: a process's start in the
kernel's clock ticks (psutil's ``create_time()`` adds the boot time, which moves when the wall
clock is stepped: every goal's sender and the arm's holder would read as gone after an NTP
step), and the files a process maps (psutil's ``memory_maps()`` parses ``smaps``, ten times the
CPU of ``maps``: 300 ms against 31 ms a sample of the faults harness's 8 nodes, every second).
"""
from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import psutil


def start_time(pid: int) -> int | None:
    """The start of the live process ``pid`` in clock ticks since boot (``/proc/<pid>/stat``
    field 22), None if there is none or only a zombie. With the pid it tells a process from a
    later one that reuses the id, whatever the wall clock does meanwhile."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except (OSError, IndexError):
        return None
    return None if fields[0] == 'Z' else int(fields[19])      # fields 3 (state) and 22


def alive(pid: int) -> bool:
    """Whether ``pid`` is a process of this machine that has not ended (zombies have)."""
    return start_time(pid) is not None


def environments() -> dict[int, dict[str, str]]:
    """The environment of every live process of this machine that is ours to read, by pid."""
    found = {}
    for process in psutil.process_iter(['status', 'environ']):
        info = process.info
        if info['status'] != psutil.STATUS_ZOMBIE and info['environ'] is not None:
            found[process.pid] = info['environ']
    return found


def command_line(pid: int) -> list[str]:
    """The arguments of the process ``pid``; none once it is gone."""
    try:
        return psutil.Process(pid).cmdline()
    except psutil.Error:
        return []


def descendants(roots: Iterable[int]) -> set[int]:
    """``roots`` and every process below them (a root that is gone stays, alone)."""
    found = set(roots)
    for pid in list(found):
        try:
            found |= {child.pid for child in psutil.Process(pid).children(recursive=True)}
        except psutil.Error:
            continue
    return found


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of the process ``pid`` so far (0 once it is gone)."""
    try:
        times = psutil.Process(pid).cpu_times()
    except psutil.Error:
        return 0.0
    return times.user + times.system


def mapped_files(directory: Path, pid: int | None = None) -> set[str]:
    """Paths under ``directory`` that a process maps (``pid``, or any whose maps are ours to
    read), from ``/proc/<pid>/maps`` (module docstring); a file removed since is named as it
    was (`` (deleted)`` dropped)."""
    prefix, mapped = f'{directory}/', set()
    for each in [pid] if pid is not None else psutil.pids():
        try:
            text = Path(f'/proc/{each}/maps').read_text()
        except OSError:
            continue                      # ended meanwhile, or not ours to read
        for line in text.splitlines():
            path = line.split(maxsplit=5)[-1] if line.count(' ') >= 5 else ''
            if path.startswith(prefix):
                mapped.add(path.removesuffix(' (deleted)'))
    return mapped


def machine_times() -> tuple[float, float]:
    """(busy, total) CPU seconds of all cores since boot: idle and I/O wait are not busy."""
    times = psutil.cpu_times()
    total = sum(times)
    return total - times.idle - times.iowait, total


def busy_share(before: tuple[float, float], after: tuple[float, float]) -> float:
    """The busy share of all cores between two :func:`machine_times` (0 if no time passed)."""
    total = after[1] - before[1]
    return (after[0] - before[0]) / total if total > 0 else 0.0
