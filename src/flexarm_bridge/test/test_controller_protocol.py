"""The controller wire protocol codec: round trips, and survival of any byte stream."""
import math
import re
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from flexarm_bridge import controller_protocol as proto
from flexarm_bridge.link_auth import CONTROLLER, OPEN_KEY, PC, LinkAuth

STATE = dict(time=12.5, positions=[0.1, 0.6, -0.5, -0.4], velocities=[0.0, 0.01, 0.0, -0.2],
             status=proto.STATUS_MOVING)


@pytest.mark.parametrize('frame_type, fields', [
    (proto.HELLO, dict(version=1, names=['joint1', 'joint2', 'joint3', 'joint4'])),
    (proto.JOINT_STATE, STATE),
    (proto.JOINT_COMMAND, dict(positions=[0.2, 0.7, -0.1, 0.3])),
    (proto.ACK, dict(acked=7, code=proto.E_LIMITS)),
    (proto.ERROR, dict(code=proto.E_MALFORMED, text='bad frame')),
    (proto.HEARTBEAT, dict(time=3.25)),
])
def test_round_trip(frame_type, fields):
    frames, errors = proto.Decoder().feed(proto.encode(frame_type, 42, **fields))
    assert errors == [] and len(frames) == 1
    assert frames[0].type == frame_type and frames[0].seq == 42 and frames[0].fields == fields


def test_byte_by_byte_and_back_to_back():
    stream = b''.join(proto.encode(proto.JOINT_STATE, i, **STATE) for i in range(5))
    decoder, frames = proto.Decoder(), []
    for byte in stream:
        got, errors = decoder.feed(bytes([byte]))
        assert errors == []
        frames += got
    assert [f.seq for f in frames] == [0, 1, 2, 3, 4]


def test_garbage_and_corruption_are_skipped_and_reported():
    good = proto.encode(proto.JOINT_COMMAND, 1, positions=[0.0, 0.5, 0.0, 0.0])
    corrupt = bytearray(proto.encode(proto.JOINT_COMMAND, 2, positions=[0.0, 0.5, 0.0, 0.0]))
    corrupt[-6] ^= 0xFF                                        # payload bit flip: bad CRC
    stream = b'\x00garbage\xfa' + good + bytes(corrupt) + b'\xfaW\xff' + good
    decoder = proto.Decoder()
    frames, errors = decoder.feed(stream)
    assert [f.seq for f in frames] == [1, 1]
    assert any('garbage' in e for e in errors) and any('CRC' in e for e in errors)
    assert decoder.rejected == 2          # the corrupt frame and the cut-off b'\xfaW\xff' one


def test_malformed_payloads_are_rejected_with_a_reason():
    def frame(frame_type, payload, version=proto.VERSION):
        head = proto.HEADER.pack(proto.MAGIC, version, frame_type, 9, len(payload)) + payload
        return head + proto.CRC.pack(zlib.crc32(head))

    nan_command = struct.pack('<B', 2) + struct.pack('<2d', 0.1, math.nan)
    short_hello = struct.pack('<HB', 1, 2) + b'\x06joint1'             # 2 names, 1 sent
    stream = (frame(proto.JOINT_COMMAND, nan_command) + frame(proto.JOINT_COMMAND, b'\x04')
              + frame(99, b'') + frame(proto.HEARTBEAT, struct.pack('<d', 1.0), version=7)
              + frame(proto.HELLO, short_hello))
    decoder = proto.Decoder()
    frames, errors = decoder.feed(stream)
    assert frames == []
    assert len(errors) == 5 and decoder.rejected == 5
    assert 'non-finite' in errors[0] and 'needs' in errors[1]
    assert 'unknown' in errors[2] and 'version 7' in errors[3] and 'HELLO' in errors[4]


def test_oversized_length_resynchronises():
    bogus = proto.HEADER.pack(proto.MAGIC, 1, proto.HEARTBEAT, 0, 60000)
    good = proto.encode(proto.HEARTBEAT, 5, time=1.0)
    frames, errors = proto.Decoder().feed(bogus + good)
    assert [f.seq for f in frames] == [5] and any('exceeds' in e for e in errors)


def test_random_bytes_never_raise_and_good_frames_get_through_after_them():
    rng = np.random.default_rng(0)
    decoder = proto.Decoder()
    for _ in range(200):                      # noise with planted magics and headers
        noise = bytearray(rng.integers(0, 256, int(rng.integers(1, 300)), dtype=np.uint8))
        noise[int(rng.integers(0, len(noise))):][:2] = proto.MAGIC
        decoder.feed(bytes(noise))
    good = b''.join(proto.encode(proto.HEARTBEAT, seq, time=2.0) for seq in range(100))
    frames, _ = decoder.feed(good)            # > MAX_PAYLOAD: any pending bogus header fails
    assert [f.seq for f in frames][-50:] == list(range(50, 100))


def test_protocol_document_examples_are_what_the_reference_code_computes():
    document = (Path(__file__).parents[1] / 'PROTOCOL.md').read_text()
    plain, auth, auth_ok, tagged = (bytes.fromhex(f.replace('|', '')) for f in re.findall(
        r'`(fa 57 [0-9a-f |]+)`', document))
    assert plain == proto.encode(proto.HEARTBEAT, 5, time=1.0)

    def vector(name: str) -> str:
        return re.search(rf'`{name}` =\s+`([0-9a-f]+)`', document).group(1)

    site, nc, np_ = bytes(range(32)), bytes(range(0xa0, 0xb0)), bytes(range(0xb0, 0xc0))
    controller, pc = LinkAuth(site, CONTROLLER, nc), LinkAuth(site, PC, np_)
    assert pc.on_hello(nc) is None
    pc_auth = pc.answer()
    assert controller.on_auth(**pc_auth) is None
    controller_proof = controller.answer()
    assert pc.on_auth_ok(**controller_proof) is None
    assert pc_auth['proof'].hex() == vector('P_pc')
    assert controller_proof['proof'].hex() == vector('P_c')
    assert controller.send_key.hex() == pc.receive_key.hex() == vector('K_c→p')
    assert pc.send_key.hex() == controller.receive_key.hex() == vector('K_p→c')
    assert auth == proto.encode(proto.AUTH, 1, OPEN_KEY, **pc_auth)
    assert auth_ok == proto.encode(proto.AUTH_OK, 2, OPEN_KEY, **controller_proof)
    assert tagged == proto.encode(proto.HEARTBEAT, 5, pc.send_key, time=1.0)
