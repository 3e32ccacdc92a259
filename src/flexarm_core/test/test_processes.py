"""Reading this machine's processes while some of them end."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from flexarm_core import processes


def test_a_child_is_listed_below_its_parent_until_it_is_reaped() -> None:
    child = subprocess.Popen([sys.executable, '-c', 'import sys; sys.stdin.read()'],
                             stdin=subprocess.PIPE)
    try:
        assert {os.getpid(), child.pid} <= set(processes.pids())
        assert child.pid in processes.descendants([os.getpid()])
        assert processes.stat_fields(child.pid)[1] == str(os.getpid())
    finally:
        child.communicate(b'', timeout=30)
    assert processes.read_text(child.pid, 'stat') is None
    assert processes.stat_fields(child.pid) is None
    assert processes.descendants([child.pid]) == {child.pid}


def test_a_process_that_ended_after_the_listing_is_skipped(tmp_path) -> None:
    """An entry of /proc whose files are gone: listed, then read as nothing."""
    (tmp_path / '7').mkdir()
    (tmp_path / '8').mkdir()
    (tmp_path / '8' / 'stat').write_text('8 (a (b) c) S 7 8 8 0')
    (tmp_path / 'self').mkdir()
    assert sorted(processes.pids(tmp_path)) == [7, 8]
    assert processes.read_text(7, 'maps', tmp_path) is None
    assert processes.stat_fields(8, tmp_path)[:2] == ['S', '7']     # a ')' in the name
    assert processes.descendants([7], tmp_path) == {7, 8}


@pytest.mark.parametrize('name', ['stat', 'maps', 'environ'])
def test_files_of_a_process_that_does_not_exist_read_as_none(name) -> None:
    assert processes.read_text(2**22 + 1, name) is None      # above pid_max's ceiling
