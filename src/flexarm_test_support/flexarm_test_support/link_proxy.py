"""A TCP relay between the PC (``flexarm_bridge``) and a robot controller, for tests and
benchmarks: it can cut the link, inject bytes towards the PC, report every plain (version 1)
protocol frame that passes with the time it arrived (``time.monotonic``, comparable across
processes), and record the raw bytes of each connection (an eavesdropper's recording).
"""
from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable

from flexarm_bridge import controller_protocol as proto
from flexarm_bridge import tcp_link

TO_CONTROLLER, TO_PC = 'to_controller', 'to_pc'
FrameObserver = Callable[[str, float, proto.Frame], None]


class LinkProxy:
    """PC -> ``127.0.0.1:listen_port`` -> relay -> ``127.0.0.1:target_port`` (controller)."""

    def __init__(self, listen_port: int, target_port: int,
                 on_frame: FrameObserver | None = None, record: bool = False) -> None:
        self._server = socket.create_server(('127.0.0.1', listen_port))
        self._server.settimeout(0.2)
        self._target = target_port
        self._on_frame = on_frame
        self._pair: tuple[socket.socket, socket.socket] | None = None
        self.connections = 0
        self._record = record
        # with ``record``: per connection, the bytes that passed each way (by direction)
        self.recorded: list[dict[str, bytearray]] = []
        self._running = True
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while self._running:
            try:
                pc, _ = self._server.accept()
            except OSError:
                continue
            try:
                controller = tcp_link.connect('127.0.0.1', self._target, timeout=2)
            except OSError:
                pc.close()                    # controller not there: the PC sees a refusal
                continue
            for s in (pc, controller):
                s.settimeout(None)
                s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._pair = (pc, controller)
            self.connections += 1
            tape = {TO_CONTROLLER: bytearray(), TO_PC: bytearray()}
            if self._record:
                self.recorded.append(tape)
            for src, dst, direction in ((pc, controller, TO_CONTROLLER),
                                        (controller, pc, TO_PC)):
                threading.Thread(target=self._pump, args=(src, dst, direction, tape[direction]),
                                 daemon=True).start()

    def _pump(self, src: socket.socket, dst: socket.socket, direction: str,
              tape: bytearray) -> None:
        decoder = proto.Decoder()
        try:
            while data := src.recv(65536):
                arrived = time.monotonic()
                if self._record:
                    tape += data
                dst.sendall(data)
                if self._on_frame is not None:
                    for frame in decoder.feed(data)[0]:
                        self._on_frame(direction, arrived, frame)
        except OSError:
            pass
        _shutdown(src, dst)

    def inject(self, data: bytes) -> None:
        """Send raw bytes to the PC as if the controller had sent them."""
        self._pair[0].sendall(data)

    def cut(self) -> None:
        """Drop the current connection (both sides see it close)."""
        _shutdown(*self._pair)

    def close(self) -> None:
        self._running = False
        self._server.close()


def _shutdown(*sockets: socket.socket) -> None:
    for s in sockets:
        try:
            s.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass          # that side is already down
