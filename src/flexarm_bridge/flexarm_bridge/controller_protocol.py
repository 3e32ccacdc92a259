"""Wire protocol between the PC (``flexarm_bridge``) and a robot controller (pure codec).

Specification for implementers: src/flexarm_bridge/PROTOCOL.md. Frames are little-endian::

    magic 0xFA 0x57 | version u8 | type u8 | seq u32 | length u16 | payload | trailer

Version 1 frames end with a CRC-32 (zlib) of everything before it; version 3 frames, the
authenticated link (:mod:`flexarm_bridge.link_auth`), with a 16-byte HMAC-SHA256 tag instead
(version 2 is withdrawn: its handshake could be replayed). :class:`Encoder` numbers and tags one
side's frames; :class:`Decoder` is incremental and never raises: garbage, a bad CRC or tag, an
unknown type, a wrong payload size, non-finite values, a replayed frame, a handshake frame out
of phase or with a wrong proof, or a frame of another version come back as errors, and it
resynchronises on the next magic.
"""
from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass, field

from flexarm_bridge.link_auth import NONCE_SIZE, OPEN_KEY, TAG_SIZE, LinkAuth, tag

MAGIC = b'\xfaW'
VERSION = 1               # plain frames, CRC-32: loopback links without a key
AUTH_VERSION = 3          # authenticated frames, HMAC tag: any link with a site key
WITHDRAWN_VERSION = 2     # tagged like version 3, refused: its handshake could be replayed
HEADER = struct.Struct('<2sBBIH')
CRC = struct.Struct('<I')
MAX_PAYLOAD = 1024

HELLO, JOINT_STATE, JOINT_COMMAND, ACK, ERROR, HEARTBEAT, AUTH, AUTH_OK = 1, 2, 3, 4, 5, 6, 7, 8
TYPE_NAMES = {HELLO: 'HELLO', JOINT_STATE: 'JOINT_STATE', JOINT_COMMAND: 'JOINT_COMMAND',
              ACK: 'ACK', ERROR: 'ERROR', HEARTBEAT: 'HEARTBEAT', AUTH: 'AUTH',
              AUTH_OK: 'AUTH_OK'}
HANDSHAKE = frozenset({HELLO, AUTH, AUTH_OK})   # under the open checksum, proofs inside

# ERROR / ACK codes
OK, E_MALFORMED, E_LIMITS, E_VERSION, E_STATE, E_BUSY = 0, 1, 2, 3, 4, 5
# JOINT_STATE status bits
STATUS_MOVING, STATUS_FAULT = 1, 2


@dataclass(frozen=True)
class Frame:
    """A decoded frame; ``authenticated``: tagged with the session key of its direction (only
    such frames of a version 3 link count as a sign of life)."""
    type: int
    seq: int
    fields: dict = field(default_factory=dict)
    authenticated: bool = False


def frame_key(auth: LinkAuth, frame_type: int, outgoing: bool) -> bytes | None:
    """Key of a version 3 frame: the open checksum for handshake frames and for ERROR before the
    session (information, never trusted), else the session key of the direction; None when the
    frame may not pass yet (a session frame before the session)."""
    if frame_type in HANDSHAKE or (frame_type == ERROR and not auth.established):
        return OPEN_KEY
    return auth.send_key if outgoing else auth.receive_key


def _floats(n: int) -> struct.Struct:
    return struct.Struct(f'<{n}d')


def encode(frame_type: int, seq: int, key: bytes | None = None, **fields) -> bytes:
    """Bytes of one frame; ``fields`` as documented per type in PROTOCOL.md.

    Without ``key`` a version 1 frame (CRC-32), with it a version 3 frame tagged with ``key``.
    """
    if frame_type == HELLO:
        names = [name.encode() for name in fields['names']]
        payload = struct.pack('<HB', fields['version'], len(names)) + b''.join(
            struct.pack('<B', len(name)) + name for name in names) + fields.get('nonce', b'')
    elif frame_type == AUTH:
        payload = fields['nonce'] + fields['proof']
    elif frame_type == AUTH_OK:
        payload = fields['proof']
    elif frame_type == JOINT_STATE:
        q, v = fields['positions'], fields['velocities']
        payload = (struct.pack('<dB', fields['time'], len(q)) + _floats(len(q)).pack(*q)
                   + _floats(len(v)).pack(*v) + struct.pack('<I', fields['status']))
    elif frame_type == JOINT_COMMAND:
        q = fields['positions']
        payload = struct.pack('<B', len(q)) + _floats(len(q)).pack(*q)
    elif frame_type == ACK:
        payload = struct.pack('<Ii', fields['acked'], fields['code'])
    elif frame_type == ERROR:
        payload = struct.pack('<i', fields['code']) + fields['text'].encode()[:MAX_PAYLOAD - 4]
    elif frame_type == HEARTBEAT:
        payload = struct.pack('<d', fields['time'])
    else:
        raise ValueError(f'unknown frame type {frame_type}')
    version = VERSION if key is None else AUTH_VERSION
    head = HEADER.pack(MAGIC, version, frame_type, seq & 0xFFFFFFFF, len(payload)) + payload
    return head + (CRC.pack(zlib.crc32(head)) if key is None else tag(key, head))


def _parse(frame_type: int, payload: bytes, version: int) -> dict:
    """Fields of a payload; ValueError with the reason when it is malformed."""
    if frame_type == HELLO:
        hello_version, n = struct.unpack_from('<HB', payload)
        names, offset = [], 3
        for _ in range(n):
            size = payload[offset]
            names.append(payload[offset + 1:offset + 1 + size].decode())
            offset += 1 + size
        nonce = NONCE_SIZE if version == AUTH_VERSION else 0
        if offset + nonce != len(payload):
            raise ValueError(f'HELLO of {n} joint names needs {offset + nonce} bytes, '
                             f'got {len(payload)}')
        fields = {'version': hello_version, 'names': names}
        return fields | {'nonce': payload[offset:]} if nonce else fields
    if frame_type == AUTH:
        if len(payload) != NONCE_SIZE + TAG_SIZE:
            raise ValueError(f'AUTH needs a {NONCE_SIZE}-byte nonce and a {TAG_SIZE}-byte '
                             f'proof, got {len(payload)} bytes')
        return {'nonce': payload[:NONCE_SIZE], 'proof': payload[NONCE_SIZE:]}
    if frame_type == AUTH_OK:
        if len(payload) != TAG_SIZE:
            raise ValueError(f'AUTH_OK needs a {TAG_SIZE}-byte proof, got {len(payload)} bytes')
        return {'proof': payload}
    if frame_type == JOINT_STATE:
        t, n = struct.unpack_from('<dB', payload)
        if len(payload) != 9 + 16 * n + 4:
            raise ValueError(f'JOINT_STATE of {n} joints needs {9 + 16 * n + 4} bytes')
        values = _floats(2 * n).unpack_from(payload, 9)
        status, = struct.unpack_from('<I', payload, 9 + 16 * n)
        fields = {'time': t, 'positions': list(values[:n]), 'velocities': list(values[n:]),
                  'status': status}
        _check_finite([t, *values])
        return fields
    if frame_type == JOINT_COMMAND:
        n, = struct.unpack_from('<B', payload)
        if len(payload) != 1 + 8 * n:
            raise ValueError(f'JOINT_COMMAND of {n} joints needs {1 + 8 * n} bytes')
        positions = list(_floats(n).unpack_from(payload, 1))
        _check_finite(positions)
        return {'positions': positions}
    if frame_type == ACK:
        acked, code = struct.unpack('<Ii', payload)
        return {'acked': acked, 'code': code}
    if frame_type == ERROR:
        code, = struct.unpack_from('<i', payload)
        return {'code': code, 'text': payload[4:].decode('utf-8', errors='replace')}
    if frame_type == HEARTBEAT:
        t, = struct.unpack('<d', payload)
        _check_finite([t])
        return {'time': t}
    raise ValueError(f'unknown frame type {frame_type}')


def _check_finite(values: list[float]) -> None:
    if not all(math.isfinite(v) for v in values):
        raise ValueError('non-finite value')


class Encoder:
    """One side's frames on one connection: version 1 without ``auth``, version 3 with it;
    sequence numbers count from 1 per connection."""

    def __init__(self, auth: LinkAuth | None = None) -> None:
        self._auth = auth
        self.seq = 0

    def encode(self, frame_type: int, **fields) -> bytes | None:
        """The next frame's bytes; None if it may not be sent yet (a session frame before the
        session: :func:`frame_key`)."""
        key = None
        if self._auth is not None:
            key = frame_key(self._auth, frame_type, outgoing=True)
            if key is None:
                return None
        self.seq += 1
        return encode(frame_type, self.seq, key, **fields)


class Decoder:
    """Bytes in, frames and errors out; survives any byte stream.

    Without ``auth`` it accepts version 1 frames only; with it, version 3 frames under the keys
    of :func:`frame_key` with increasing sequence numbers (session frames), and hands the
    handshake frames to ``auth`` as they come, so the session starts at the frame that starts
    it (a session frame right behind AUTH_OK in the same read passes). ``rejected`` counts the
    frames rejected so far (a bad length, CRC, tag, version, sequence, payload, phase or proof);
    skipped garbage between frames is reported but not counted. A tagged frame of a known type
    whose tag fails is consumed whole: one rejection, and nothing inside it (its tag and nonces
    are random bytes) is ever taken for the start of another frame.
    """

    def __init__(self, auth: LinkAuth | None = None) -> None:
        self._buffer = bytearray()
        self._auth = auth
        self.rejected = 0

    def feed(self, data: bytes) -> tuple[list[Frame], list[str]]:
        self._buffer += data
        frames, errors = [], []
        while True:
            start = self._buffer.find(MAGIC)
            if start < 0:
                if len(self._buffer) > 1:
                    errors.append(f'{len(self._buffer) - 1} bytes of garbage skipped')
                    del self._buffer[:-1]          # keep a possible first magic byte
                break
            if start > 0:
                errors.append(f'{start} bytes of garbage skipped')
                del self._buffer[:start]
            if len(self._buffer) < HEADER.size:
                break
            _, version, frame_type, seq, length = HEADER.unpack_from(self._buffer)
            if length > MAX_PAYLOAD:
                errors.append(f'frame length {length} exceeds {MAX_PAYLOAD}: resynchronising')
                self.rejected += 1
                del self._buffer[:1]
                continue
            end = HEADER.size + length
            if len(self._buffer) < end + _trailer(version):
                break
            authenticated = (version == AUTH_VERSION and self._auth is not None
                             and frame_key(self._auth, frame_type, False) is not OPEN_KEY)
            verdict = self._check(version, frame_type, seq, end)
            if verdict is not None:
                error, resync = verdict
                errors.append(error)
                self.rejected += 1
                del self._buffer[:1 if resync else end + _trailer(version)]
                continue
            payload = bytes(self._buffer[HEADER.size:end])
            del self._buffer[:end + _trailer(version)]
            try:
                fields = _parse(frame_type, payload, version)
            except (ValueError, IndexError, struct.error) as exc:
                errors.append(f'malformed {TYPE_NAMES.get(frame_type, frame_type)}: {exc}')
                self.rejected += 1
                continue
            refusal = self._handshake(frame_type, fields)
            if refusal is not None:
                errors.append(refusal)
                self.rejected += 1
                continue
            frames.append(Frame(frame_type, seq, fields, authenticated))
        return frames, errors

    def _handshake(self, frame_type: int, fields: dict) -> str | None:
        """Hand a handshake frame to the link's authentication; why it refused it, if it did."""
        if frame_type not in HANDSHAKE or (self._auth is None and frame_type == HELLO):
            return None
        if self._auth is None:
            return f'{TYPE_NAMES[frame_type]} refused: version {VERSION} has no handshake'
        if frame_type == HELLO:
            return self._auth.on_hello(fields['nonce'])
        if frame_type == AUTH:
            return self._auth.on_auth(fields['nonce'], fields['proof'])
        return self._auth.on_auth_ok(fields['proof'])

    def _check(self, version: int, frame_type: int, seq: int, end: int) -> tuple[str, bool] | None:
        """Why the complete frame at the buffer's start is refused, and whether to resync
        (drop one byte: it may not be a frame at all) rather than skip it; None if it is good.

        A CRC mismatch resynchronises: the damage may be in the header, length included. A tag
        mismatch skips the frame whole when its header is one this link speaks (version 3, a
        known type; the length was checked): tags fail on complete frames (changed, foreign,
        reflected, another key), and rescanning the random bytes of a tag or nonce would find a
        false magic in about 1 frame of 4400, making one refused frame count twice or hold back
        the next good frame until up to a kilobyte of later bytes arrived.
        """
        name = TYPE_NAMES.get(frame_type, f'type {frame_type}')
        if version == WITHDRAWN_VERSION:
            return (f'protocol version {version} {name} refused: withdrawn (its handshake can '
                    f'be replayed); this link speaks version '
                    f'{VERSION if self._auth is None else AUTH_VERSION}', False)
        if version == AUTH_VERSION:
            if self._auth is None:
                return (f'authenticated (version {AUTH_VERSION}) {name} refused: this side has '
                        'no link key', False)
            key = frame_key(self._auth, frame_type, outgoing=False)
            if key is None:
                return f'{name} before the session: refused', False
            if tag(key, self._buffer[:end]) != self._buffer[end:end + TAG_SIZE]:
                if frame_type not in TYPE_NAMES:
                    return 'authentication tag mismatch: resynchronising', True
                return f'authentication tag mismatch: {name} refused', False
            if key is not OPEN_KEY and not self._auth.fresh(seq):
                return f'replayed or reordered {name} (sequence {seq}) refused', False
            return None
        crc, = CRC.unpack_from(self._buffer, end)
        if crc != zlib.crc32(self._buffer[:end]):
            return 'CRC mismatch: resynchronising', True
        if version != VERSION:
            return f'protocol version {version} not supported (want {VERSION})', False
        if self._auth is not None:
            return (f'unauthenticated (version {VERSION}) {name} refused: this link requires '
                    'authentication', False)
        return None


def _trailer(version: int) -> int:
    return TAG_SIZE if version in (AUTH_VERSION, WITHDRAWN_VERSION) else CRC.size
