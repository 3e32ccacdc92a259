"""Reading this machine's processes while some of them end."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import psutil

from flexarm_core import processes

# Maps a file of argv[1], then waits for its standard input to close.
MAPPER = 'import mmap, sys; f = open(sys.argv[1], "r+b"); m = mmap.mmap(f.fileno(), 0); ' \
         'print("mapped", flush=True); sys.stdin.read()'
GONE = 2**22 + 1                      # above pid_max's ceiling: never a process


def test_a_child_is_known_below_its_parent_until_it_ends() -> None:
    child = subprocess.Popen([sys.executable, '-c', 'import sys; sys.stdin.read()'],
                             stdin=subprocess.PIPE, env={**os.environ, 'MARK': 'child'})
    try:
        assert processes.alive(child.pid)
        assert processes.start_time(child.pid) == processes.start_time(child.pid)
        assert child.pid in processes.descendants([os.getpid()])
        assert processes.environments()[child.pid]['MARK'] == 'child'
        assert processes.command_line(child.pid)[1:3] == ['-c', 'import sys; sys.stdin.read()']
        child.stdin.close()
        deadline = time.monotonic() + 30.0
        while processes.alive(child.pid) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert psutil.Process(child.pid).status() == psutil.STATUS_ZOMBIE   # ended, unreaped
        assert not processes.alive(child.pid) and child.pid not in processes.environments()
    finally:
        child.kill()
        child.wait(timeout=30)
    assert not processes.alive(child.pid)
    assert processes.descendants([child.pid]) == {child.pid}


def test_a_process_that_does_not_exist_reads_as_gone() -> None:
    assert processes.start_time(GONE) is None and not processes.alive(GONE)
    assert processes.command_line(GONE) == [] and processes.cpu_seconds(GONE) == 0.0
    assert processes.descendants([GONE]) == {GONE}
    assert processes.mapped_files(Path('/'), GONE) == set()


def test_the_files_a_process_maps_are_named(tmp_path: Path) -> None:
    path = tmp_path / 'segment'
    path.write_bytes(b'\0' * 4096)
    child = subprocess.Popen([sys.executable, '-c', MAPPER, str(path)], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == 'mapped'
        assert processes.mapped_files(tmp_path, child.pid) == {str(path)}
        assert str(path) in processes.mapped_files(tmp_path)
    finally:
        child.communicate('', timeout=30)
    assert processes.mapped_files(tmp_path) == set()


def test_cpu_time_is_counted_for_a_process_and_the_machine() -> None:
    own, machine = processes.cpu_seconds(os.getpid()), processes.machine_times()
    deadline = time.process_time() + 0.2
    while time.process_time() < deadline:
        pass
    assert processes.cpu_seconds(os.getpid()) - own >= 0.1
    after = processes.machine_times()
    assert 0.0 < processes.busy_share(machine, after) <= 1.0
    assert processes.busy_share(after, after) == 0.0
