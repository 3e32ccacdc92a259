"""Wire protocol between the PC (``flexarm_bridge``) and a robot controller (pure codec).

Specification for implementers: src/flexarm_control/PROTOCOL.md. Frames are little-endian::

    magic 0xFA 0x57 | version u8 | type u8 | seq u32 | length u16 | payload | crc32 u32

The CRC-32 (zlib) covers everything before it. :class:`Decoder` is incremental and never
raises: garbage, a corrupt CRC, an unknown type, a wrong payload size or non-finite values come
back as errors, and it resynchronises on the next magic.
"""
from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass, field

MAGIC = b'\xfaW'
VERSION = 1
HEADER = struct.Struct('<2sBBIH')
CRC = struct.Struct('<I')
MAX_PAYLOAD = 1024

HELLO, JOINT_STATE, JOINT_COMMAND, ACK, ERROR, HEARTBEAT = 1, 2, 3, 4, 5, 6
TYPE_NAMES = {HELLO: 'HELLO', JOINT_STATE: 'JOINT_STATE', JOINT_COMMAND: 'JOINT_COMMAND',
              ACK: 'ACK', ERROR: 'ERROR', HEARTBEAT: 'HEARTBEAT'}

# ERROR / ACK codes
OK, E_MALFORMED, E_LIMITS, E_VERSION, E_STATE, E_BUSY = 0, 1, 2, 3, 4, 5
# JOINT_STATE status bits
STATUS_MOVING, STATUS_FAULT = 1, 2


@dataclass(frozen=True)
class Frame:
    type: int
    seq: int
    fields: dict = field(default_factory=dict)


def _floats(n: int) -> struct.Struct:
    return struct.Struct(f'<{n}d')


def encode(frame_type: int, seq: int, **fields) -> bytes:
    """Bytes of one frame; ``fields`` as documented per type in PROTOCOL.md."""
    if frame_type == HELLO:
        names = [name.encode() for name in fields['names']]
        payload = struct.pack('<HB', fields['version'], len(names)) + b''.join(
            struct.pack('<B', len(name)) + name for name in names)
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
    head = HEADER.pack(MAGIC, VERSION, frame_type, seq & 0xFFFFFFFF, len(payload)) + payload
    return head + CRC.pack(zlib.crc32(head))


def _parse(frame_type: int, payload: bytes) -> dict:
    """Fields of a payload; ValueError with the reason when it is malformed."""
    if frame_type == HELLO:
        version, n = struct.unpack_from('<HB', payload)
        names, offset = [], 3
        for _ in range(n):
            size = payload[offset]
            names.append(payload[offset + 1:offset + 1 + size].decode())
            offset += 1 + size
        if offset != len(payload):
            raise ValueError(f'HELLO of {n} joint names needs {offset} bytes, got {len(payload)}')
        return {'version': version, 'names': names}
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


class Decoder:
    """Bytes in, frames and errors out; survives any byte stream.

    ``rejected`` counts the frames rejected so far (a bad length, CRC, version or payload);
    skipped garbage between frames is reported but not counted.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()
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
            if len(self._buffer) < end + CRC.size:
                break
            crc, = CRC.unpack_from(self._buffer, end)
            if crc != zlib.crc32(self._buffer[:end]):
                errors.append('CRC mismatch: resynchronising')
                self.rejected += 1
                del self._buffer[:1]
                continue
            payload = bytes(self._buffer[HEADER.size:end])
            del self._buffer[:end + CRC.size]
            if version != VERSION:
                errors.append(f'protocol version {version} not supported (want {VERSION})')
                self.rejected += 1
                continue
            try:
                frames.append(Frame(frame_type, seq, _parse(frame_type, payload)))
            except (ValueError, IndexError, struct.error) as exc:
                errors.append(f'malformed {TYPE_NAMES.get(frame_type, frame_type)}: {exc}')
                self.rejected += 1
        return frames, errors
