"""What a process owns of Fast DDS's shared memory and what nobody uses any more
(:mod:`flexarm_core.dds_shm`), on files of a temporary folder."""
import errno
import os
import subprocess
import sys
from pathlib import Path

from flexarm_core.dds_shm import shm_in_use


def test_the_shared_memory_a_killed_process_owned_is_removed_and_shared_ports_kept(tmp_path):
    import fcntl
    import mmap

    from flexarm_core.dds_shm import owned_shm, remove_shm_of_dead

    for name in ('fastrtps_abc', 'fastrtps_abc_el', 'fastrtps_other', 'fastrtps_other_el',
                 'fastrtps_port1', 'sem.fastrtps_port1_mutex', 'fastrtps_port2',
                 'sem.fastrtps_port2_mutex'):
        (tmp_path / name).write_bytes(b'\0' * 4096)
    # A participant: holds its segment's lock, maps it and port 1 and port 2.
    owner = subprocess.Popen([sys.executable, '-c', (
        'import fcntl, mmap, sys, pathlib\n'
        f'd = pathlib.Path({str(tmp_path)!r})\n'
        'lock = open(d / "fastrtps_abc_el", "rb"); fcntl.flock(lock, fcntl.LOCK_EX)\n'
        'files = [open(d / p, "r+b") for p in ("fastrtps_abc", "fastrtps_port1",\n'
        '                                      "fastrtps_port2")]\n'
        'maps = [mmap.mmap(f.fileno(), 4096) for f in files]\n'
        'print("ready", flush=True); sys.stdin.read()\n')],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert owner.stdout.readline().strip() == 'ready'
        with open(tmp_path / 'fastrtps_other_el', 'rb') as other_lock, \
                open(tmp_path / 'fastrtps_port1', 'r+b') as port, \
                mmap.mmap(port.fileno(), 4096):            # another participant on port 1
            fcntl.flock(other_lock, fcntl.LOCK_EX)
            owned = owned_shm(owner.pid, tmp_path)
            assert sorted(p.name for p in owned) == [
                'fastrtps_abc', 'fastrtps_abc_el', 'fastrtps_port1', 'fastrtps_port2',
                'sem.fastrtps_port1_mutex', 'sem.fastrtps_port2_mutex']
            owner.kill()
            owner.wait(10)
            assert remove_shm_of_dead(owned, tmp_path) == 4     # port 1 is still mapped...
            assert sorted(p.name for p in owned) == ['fastrtps_port1', 'sem.fastrtps_port1_mutex']
        assert remove_shm_of_dead(owned, tmp_path) == 2         # ... until its last user left
        assert owned == []
        assert sorted(p.name for p in tmp_path.iterdir()) == [
            'fastrtps_other', 'fastrtps_other_el']
    finally:
        owner.kill()
        owner.wait(10)
        owner.stdin.close()
        owner.stdout.close()


def test_listing_the_mapped_shared_memory_survives_a_process_being_reaped(monkeypatch,
                                                                             tmp_path) -> None:
    """The kernel answers ESRCH, not ENOENT, for the files of a process being reaped, and
    pathlib's globbing (which stats what it matches) let that through: a node's start
    failed with ProcessLookupError in the middle of its search for stale shared memory."""
    real_stat = Path.stat

    def reaped(path: Path, *args, **kwargs) -> os.stat_result:
        if path.parts[:2] == ('/', 'proc') and path.name == 'maps':
            raise ProcessLookupError(errno.ESRCH, os.strerror(errno.ESRCH), str(path))
        return real_stat(path, *args, **kwargs)

    monkeypatch.setattr(Path, 'stat', reaped)
    assert shm_in_use(tmp_path) == set()
