"""Fast DDS's shared memory in /dev/shm: what a process owns of it and what nobody uses any
more (pure: /proc and the files, no rclpy). A process killed by a signal leaves its segments
and the ports it listened on behind, and gone it can no longer be asked: whoever started it (the
launcher) or it itself, while alive, notes what it owns and removes that once it is gone.
"""
from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable
from pathlib import Path

from flexarm_core import processes
from flexarm_core.graph_locks import FileKey, file_key, held_locks

SHM_DIR = Path('/dev/shm')


def owned_shm(pid: int, shm_dir: Path = SHM_DIR) -> list[Path]:
    """The Fast DDS shared-memory files of the live process ``pid`` that nobody else can
    remove once it dies by SIGKILL: its segments and the ports it listens on (a file
    ``fastrtps_*`` it maps whose ``_el`` file it holds the flock of, read from /proc/locks;
    Fast DDS maps a segment for its owner's whole life) with their lock files, and the port
    files (``fastrtps_port<N>`` with ``sem.fastrtps_port<N>_mutex``) it maps.

    Asked of a named process instead of guessed from the whole folder: a file that merely
    looks unused may be one another participant of the machine is just creating.
    """
    held = _flocks(pid)
    owned = []
    for path in sorted(map(Path, processes.mapped_files(shm_dir, pid))):
        lock = path.with_name(f'{path.name}_el')
        with contextlib.suppress(OSError):
            if file_key(lock.stat()) in held:
                owned += [lock, path]
        if path.name.startswith('fastrtps_port'):
            owned += [path, shm_dir / f'sem.{path.name}_mutex']
    return owned


def remove_shm_of_dead(files: list[Path], shm_dir: Path = SHM_DIR) -> int:
    """Remove ``files`` (what processes that are gone left of :func:`owned_shm`); how many
    were removed. A segment goes although others may still map it (they opened it to write to
    its dead owner; their mappings outlive the name). A port stays while another participant
    uses it (:func:`shm_in_use`): every listener on that port shares it, and its last user
    removes it, unless a dead process still counts as one. So a port in use stays in ``files``
    for a later call (a node's restart, the graph's stop); the rest leaves the list."""
    files[:] = [f for f in files if os.path.lexists(f)]
    if not files:
        return 0
    in_use = shm_in_use(shm_dir)
    kept = list(dict.fromkeys(f for f in files if 'fastrtps_port' in f.name and str(f) in in_use))
    removed = _unlink(*{f for f in files if f not in kept})
    files[:] = kept
    return removed


def listened_ports(owned: Iterable[Path]) -> list[Path]:
    """The ports of ``owned`` (:func:`owned_shm`) its process listened on (it held their
    lock), with their lock and mutex files."""
    return [path for lock in owned
            if lock.name.startswith('fastrtps_port') and lock.name.endswith('_el')
            for port in [lock.name.removesuffix('_el')]
            for path in (lock, lock.with_name(port), lock.with_name(f'sem.{port}_mutex'))]


def shm_in_use(shm_dir: Path = SHM_DIR) -> set[str]:
    """Files of ``shm_dir`` a live process maps or holds a lock on, with the lock and mutex
    files of every mapped port."""
    mapped = processes.mapped_files(shm_dir)
    used = set(mapped)
    for path in mapped:
        used |= {f'{path}_el', str(shm_dir / f'sem.{Path(path).name}_mutex')}
    held = _flocks()
    for path in shm_dir.glob('fastrtps_*'):
        try:
            key = file_key(path.stat())
        except OSError:
            continue
        if key in held:
            used.add(str(path))
    return used


def _flocks(pid: int | None = None) -> set[FileKey]:
    """The files flock-ed by ``pid`` (by any process if None)."""
    return {key for key, holder in held_locks() if pid is None or holder == pid}


def _unlink(*paths: Path) -> int:
    """Remove ``paths``; how many were removed."""
    removed = 0
    for path in paths:
        try:
            path.unlink()
            removed += 1
        except OSError:
            pass
    return removed
