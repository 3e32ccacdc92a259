"""This machine's processes, read from /proc without tripping over one that ends meanwhile.

A process can end between the listing of /proc and the reading of its files. Reading a file
of a process that is gone raises an ``OSError`` (ENOENT, or ESRCH while it is being reaped),
which pathlib's ``exists()`` lets through: ``Path('/proc').glob('[0-9]*/maps')`` stats every
candidate and raised ``ProcessLookupError`` in the middle of a listing. So the listing here is
of names only, and every file is read once, inside a ``try``.
"""
from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

PROC = Path('/proc')


def pids(proc: Path = PROC) -> list[int]:
    """The process ids /proc lists now (names only: nothing of a process is read)."""
    with os.scandir(proc) as entries:
        return [int(entry.name) for entry in entries if entry.name.isdigit()]


def read_text(pid: int, name: str, proc: Path = PROC) -> str | None:
    """``/proc/<pid>/<name>``, or None when the process is gone or not ours to read."""
    try:
        return (proc / str(pid) / name).read_text()
    except OSError:
        return None


def stat_fields(pid: int, proc: Path = PROC) -> list[str] | None:
    """The fields of ``/proc/<pid>/stat`` after the command name (state first, then the
    parent's pid), or None when the process is gone."""
    text = read_text(pid, 'stat', proc)
    fields = text.rsplit(')', 1)[1].split() if text and ')' in text else []
    return fields if len(fields) > 1 else None


def descendants(roots: Iterable[int], proc: Path = PROC) -> set[int]:
    """``roots`` and every process below them."""
    children: dict[int, list[int]] = {}
    for pid in pids(proc):
        fields = stat_fields(pid, proc)
        if fields is not None:
            children.setdefault(int(fields[1]), []).append(pid)
    found, todo = set(), list(roots)
    while todo:
        pid = todo.pop()
        found.add(pid)
        todo += children.get(pid, [])
    return found
