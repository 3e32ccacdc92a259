"""A node run by :func:`flexarm_core.ros.node_main.run` that signals itself in the middle of its
work, for test_node_main: ``python signalled_node.py SIGNAL REPORT``.

Its timer callback sends SIGNAL to its own process and then works on for a while, watching
whether the context stays up meanwhile; a work thread (:class:`Offload`) is in a job at that
moment too. What it saw is appended to REPORT, one word a line.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import time

from rclpy.node import Node

from flexarm_core.ros.node_main import Offload, run

WORK = 0.5   # [s] the callback and the job go on after the signal


class SignalledNode(Node):
    def __init__(self, sig: int, report: str) -> None:
        super().__init__('signalled_node')
        self._sig, self._report = sig, report
        self._job_started = threading.Event()
        self._job_ended = threading.Event()
        self._work = Offload(self, 1)
        self._job = self.create_timer(0.01, self._work.wrap(self._job_body))
        self._timer = self.create_timer(0.05, self._signal_myself)

    def _note(self, word: str) -> None:
        with open(self._report, 'a', encoding='utf-8') as f:
            f.write(word + '\n')

    def _job_body(self) -> None:
        """Work in a thread of its own, polling the context as the nodes' waits do."""
        self.destroy_timer(self._job)
        self._job_started.set()
        deadline = time.monotonic() + 2 * WORK
        while self.context.ok() and time.monotonic() < deadline:
            time.sleep(0.02)
        self._job_ended.set()

    def _signal_myself(self) -> None:
        if not self._job_started.is_set():
            return
        self.destroy_timer(self._timer)
        self._note('callback entered')
        os.kill(os.getpid(), self._sig)
        end = time.monotonic() + WORK
        while time.monotonic() < end:
            if not self.context.ok():
                self._note('context shut down during the callback')
                break
        self._note('callback completed')

    def destroy_node(self) -> None:
        self._work.shutdown()
        self._note('job ended before destroy' if self._job_ended.is_set()
                   else 'job still running at destroy')
        super().destroy_node()
        self._note('destroyed')


if __name__ == '__main__':
    signum, path = signal.Signals[sys.argv[1]], sys.argv[2]
    run(lambda: SignalledNode(signum, path), [])
