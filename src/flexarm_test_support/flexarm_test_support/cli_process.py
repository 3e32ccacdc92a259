"""``flexarm`` commands as processes of a node test, read line by line as they run, and none left
running once the test ends (the autouse fixture :func:`no_cli_left`, imported into the test
module that uses :class:`Cli`)."""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator

import pytest

from flexarm_core import liveness


class Cli:
    """A ``flexarm`` process; its stdout and stderr lines as they arrive. Every one still
    running when its test ends is killed and reaped (:func:`no_cli_left`)."""

    running: list[Cli] = []

    def __init__(self, *args: str, domain_id: int) -> None:
        Cli.running.append(self)
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'flexarm_cli', *args, '--domain-id', str(domain_id)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env={**os.environ, 'PYTHONUNBUFFERED': '1'})
        self.out: list[str] = []
        self.err: list[str] = []
        self._readers = [threading.Thread(target=self._read, args=(stream, lines), daemon=True)
                         for stream, lines in ((self.process.stdout, self.out),
                                               (self.process.stderr, self.err))]
        for reader in self._readers:
            reader.start()

    @staticmethod
    def _read(stream, lines: list[str]) -> None:
        for line in stream:
            lines.append(line.rstrip('\n'))

    def wait_line(self, text: str, timeout: float) -> None:
        """Until a line of stdout or stderr (goal feedback) holds ``text``."""
        deadline = time.monotonic() + liveness.limit(timeout)
        while not any(text in line for line in self.out + self.err):
            ended = self.process.poll() is not None
            if ended:          # its last lines may still be on their way to the readers
                self._join_readers()
            if ended and any(text in line for line in self.out + self.err):
                return
            if time.monotonic() > deadline or ended:
                self.process.kill()
                pytest.fail(f'no line with {text!r} within {timeout} s: {self.out} {self.err}')
            time.sleep(0.02)

    def _join_readers(self) -> None:
        for reader in self._readers:
            reader.join(timeout=liveness.limit(5.0))

    def finish(self, timeout: float) -> tuple[int, str]:
        """Exit code and stderr, once the process has ended (killed after ``timeout``)."""
        try:
            code = self.process.wait(liveness.limit(timeout))
        except subprocess.TimeoutExpired:
            self.process.kill()
            pytest.fail(f'flexarm still ran after {timeout} s: {self.out} {self.err}')
        self._join_readers()
        return code, '\n'.join(self.err)


@pytest.fixture(autouse=True)
def no_cli_left() -> Iterator[None]:
    yield
    while Cli.running:
        process = Cli.running.pop().process
        if process.poll() is None:
            process.kill()
        process.wait(10.0)
