"""Replay and reflection attacks on the controller link, for tests and benchmarks: a peer
without the site key, armed with frames recorded from genuine connections, tries to make a
controller accept a handshake (:func:`replay_attacks`), or plays a controller to a PC
(:class:`KeylessController`).

Frames are told apart by their headers only (magic, version, type, length), not by tags, so
the attacks and their verdicts mean the same for any protocol version on the wire.
"""
from __future__ import annotations

import socket
import threading
import time
from dataclasses import dataclass, field

from flexarm_bridge import controller_protocol as proto
from flexarm_bridge import tcp_link
from flexarm_bridge.link_auth import PC, LinkAuth

# What a controller sends only once it accepted a handshake: its proof, or session frames.
ACCEPTED = frozenset({proto.AUTH_OK, proto.JOINT_STATE, proto.ACK, proto.HEARTBEAT})
TAGGED_VERSIONS = (2, 3)   # trailer: a 16-byte tag (else a 4-byte CRC)
REPLAY_EVERY = 0.3         # [s] between two replays of a HELLO (as in the security test)


def split_frames(data: bytes) -> list[bytes]:
    """The whole frames in ``data``, in order, cut by their headers; a header with an
    impossible length is skipped, a frame cut off at the end left out."""
    frames, at = [], 0
    while (at := data.find(proto.MAGIC, at)) >= 0 and at + proto.HEADER.size <= len(data):
        _, version, _, _, length = proto.HEADER.unpack_from(data, at)
        if length > proto.MAX_PAYLOAD:
            at += 1
            continue
        end = at + proto.HEADER.size + length + (16 if version in TAGGED_VERSIONS else 4)
        if end > len(data):
            break                     # still arriving
        frames.append(data[at:end])
        at = end
    return frames


def frame_type(frame: bytes) -> int:
    return frame[3]


@dataclass
class Recording:
    """The raw bytes of one genuine connection, each way."""
    to_controller: bytes
    to_pc: bytes


def connect(port: int, host: str = '127.0.0.1', timeout: float = 20.0) -> socket.socket:
    """A TCP connection to ``port``, retried while nothing listens there yet (``timeout``)."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            conn = tcp_link.connect(host, port, timeout=1.0)
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)
            continue
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return conn


@dataclass
class Exchange:
    """What one connection of a keyless peer to a controller came to."""
    name: str
    received: list[int] = field(default_factory=list)   # frame types from the controller
    held_s: float = 0.0          # until the controller closed it, or the attempt ended
    closed: bool = False         # closed by the controller

    @property
    def busy(self) -> bool:
        """Refused at once because another PC holds the link (nothing was tried)."""
        return self.received[:1] == [proto.ERROR] and proto.HELLO not in self.received

    @property
    def accepted(self) -> bool:
        return bool(ACCEPTED & set(self.received))


def exchange(port: int, name: str, send: list[bytes], seconds: float, repeat: bool = False,
             reflect: bool = False, host: str = '127.0.0.1',
             stop: threading.Event | None = None) -> Exchange:
    """Connect to a controller as a peer without the key: wait for its HELLO, then send
    ``send`` (its own HELLO with ``reflect``), again every :data:`REPLAY_EVERY` s with
    ``repeat``, and read until it closes the connection, ``seconds`` passed or ``stop``.
    Refused as busy (the previous PC not yet gone), it connects again while time is left."""
    start = time.monotonic()
    while True:
        result = _exchange(port, name, send, seconds, repeat, reflect, host, stop)
        if not result.busy or time.monotonic() - start > seconds:
            return result
        time.sleep(0.05)


def _exchange(port: int, name: str, send: list[bytes], seconds: float, repeat: bool,
              reflect: bool, host: str, stop: threading.Event | None) -> Exchange:
    result, buffer = Exchange(name), b''
    with connect(port, host) as conn:
        conn.settimeout(0.05)
        start = time.monotonic()
        sent_at: float | None = None
        while (time.monotonic() - start < seconds
               and not (stop is not None and stop.is_set())):
            frames = split_frames(buffer)
            hello = bool(frames) and frame_type(frames[0]) == proto.HELLO
            if hello and (sent_at is None or repeat and
                          time.monotonic() - sent_at >= REPLAY_EVERY):
                try:
                    conn.sendall(b''.join(frames[:1] if reflect else send))
                except OSError:
                    result.closed = True
                    break
                sent_at = time.monotonic()
            try:
                data = conn.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                data = b''
            if not data:
                result.closed = True
                break
            buffer += data
        result.held_s = time.monotonic() - start
    result.received = [frame_type(f) for f in split_frames(buffer)]
    return result


@dataclass
class AttackReport:
    exchanges: list[Exchange]

    @property
    def replay_accepted(self) -> int:
        """Replayed or reflected handshakes the controller accepted (answered with AUTH_OK
        or session frames)."""
        return sum(e.accepted for e in self.exchanges)

    @property
    def busy(self) -> int:
        """Attempts refused as busy: they tested nothing (a PC held the link)."""
        return sum(e.busy for e in self.exchanges)

    @property
    def longest_hold_s(self) -> float:
        return max((e.held_s for e in self.exchanges), default=0.0)


def replay_attacks(port: int, recording: Recording, seconds: float = 3.0,
                   host: str = '127.0.0.1') -> AttackReport:
    """Against the controller on ``port`` (no PC connected), one connection each: its own HELLO
    reflected every 0.3 s; the PC's bytes of ``recording`` (its AUTH and what followed)
    replayed; the controller's bytes of ``recording`` (HELLO, AUTH_OK, ...) reflected back.
    Each lasts until the controller closes it or ``seconds``."""
    attempts = (('HELLO reflected', [], True, True),
                ('AUTH of an earlier connection replayed',
                 split_frames(recording.to_controller), False, False),
                ('controller frames of an earlier connection reflected',
                 split_frames(recording.to_pc), False, False))
    return AttackReport([exchange(port, name, send, seconds, repeat, reflect, host)
                         for name, send, repeat, reflect in attempts])


def record_session(port: int, site_key: bytes, states: int | None = 10,
                   stop: threading.Event | None = None, host: str = '127.0.0.1',
                   timeout: float = 10.0) -> Recording:
    """A genuine session with the site key as the reference PC runs it (handshake, then a
    HEARTBEAT every 0.2 s), recorded raw both ways: until ``states`` joint states came, or with
    ``states=None`` until ``stop`` is set. ConnectionError if the controller refuses it or
    sends no joint state within ``timeout``."""
    auth = LinkAuth(site_key, PC)
    encoder, decoder = proto.Encoder(auth), proto.Decoder(auth)
    sent, received = bytearray(), bytearray()
    got, start, beat = 0, time.monotonic(), 0.0
    with connect(port, host) as conn:
        conn.settimeout(0.05)
        while (got < states if states is not None else not stop.is_set()):
            if not got and time.monotonic() - start > timeout:
                raise ConnectionError(f'no joint state within {timeout:g} s')
            replies = []
            if auth.established and time.monotonic() - beat >= 0.2:
                replies.append(encoder.encode(proto.HEARTBEAT, time=time.monotonic()))
                beat = time.monotonic()
            try:
                data = conn.recv(65536)
            except TimeoutError:
                data = None
            if data == b'':
                raise ConnectionError(f'the controller closed the session: {bytes(received)!r}')
            frames, errors = decoder.feed(data or b'')
            received += data or b''
            if errors:
                raise ConnectionError(f'the controller refused the session: {errors}')
            for frame in frames:
                if frame.type == proto.HELLO:
                    replies.append(encoder.encode(proto.AUTH, **auth.answer()))
                got += frame.type == proto.JOINT_STATE
            for reply in replies:
                conn.sendall(reply)
                sent += reply
    return Recording(bytes(sent), bytes(received))


def replay_accepted(port: int, site_key: bytes, seconds: float = 3.0,
                    host: str = '127.0.0.1') -> int:
    """How many replayed or reflected handshakes the controller on ``port`` accepted, after
    recording one genuine session with ``site_key`` (no PC may hold the link meanwhile)."""
    return replay_attacks(port, record_session(port, site_key, host=host), seconds,
                          host).replay_accepted


class KeylessController:
    """A fake controller without the key on ``127.0.0.1:port``: to every PC that connects it
    sends ``hello`` (recorded from a genuine controller), again every 0.3 s with ``repeat``,
    and sends back (reflects) every frame the PC sends with ``reflect``. Records per
    connection the frame types it got and when it opened and closed."""

    def __init__(self, port: int, hello: bytes, repeat: bool = False,
                 reflect: bool = False) -> None:
        self._server = socket.create_server(('127.0.0.1', port))
        self._server.settimeout(0.1)
        self._hello, self._repeat, self._reflect = hello, repeat, reflect
        self.connections: list[dict] = []      # {'opened', 'closed', 'received'}
        self._running = True
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while self._running:
            try:
                conn, _ = self._server.accept()
            except OSError:
                continue
            record = {'opened': time.monotonic(), 'closed': None, 'received': []}
            self.connections.append(record)
            threading.Thread(target=self._serve, args=(conn, record), daemon=True).start()

    def _serve(self, conn: socket.socket, record: dict) -> None:
        conn.settimeout(0.05)
        buffer, sent_at, handled = b'', 0.0, 0
        with conn:
            while self._running:
                try:
                    if sent_at == 0.0 or self._repeat and (
                            time.monotonic() - sent_at >= REPLAY_EVERY):
                        conn.sendall(self._hello)
                        sent_at = time.monotonic()
                    data = conn.recv(65536)
                except TimeoutError:
                    continue
                except OSError:
                    data = b''
                if not data:
                    break
                buffer += data
                frames = split_frames(buffer)[handled:]
                handled += len(frames)
                record['received'] += [frame_type(f) for f in frames]
                if self._reflect and frames:
                    try:
                        conn.sendall(b''.join(frames))
                    except OSError:
                        break
        record['closed'] = time.monotonic()

    def close(self) -> None:
        self._running = False
        self._server.close()


def first_frame(port: int, host: str = '127.0.0.1', timeout: float = 10.0) -> bytes:
    """The first frame a controller sends on a new connection (its HELLO, or a refusal)."""
    buffer = b''
    with connect(port, host) as conn:
        conn.settimeout(timeout)
        while not (frames := split_frames(buffer)):
            data = conn.recv(65536)
            if not data:
                raise ConnectionError('the controller closed the connection without a frame')
            buffer += data
    return frames[0]

