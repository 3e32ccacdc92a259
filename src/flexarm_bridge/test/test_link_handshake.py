"""The version 3 handshake state machines of both roles (pure), and how the codec applies them:
each side trusts only a proof bound to its own fresh nonce; handshake frames never count."""
import random

import pytest

from flexarm_bridge import controller_protocol as proto
from flexarm_bridge.link_auth import CONTROLLER, KEY_BYTES, PC, LinkAuth, Phase

SITE_KEY = bytes(range(KEY_BYTES))
NAMES = ['joint1', 'joint2', 'joint3', 'joint4']
STATE = dict(time=1.0, positions=[0.1, 0.6, -0.4, -0.3], velocities=[0.0] * 4, status=0)


def nonces(seed: int) -> tuple[bytes, bytes]:
    """(Nc, Np) of one connection, drawn from ``seed``."""
    rng = random.Random(seed)
    return rng.randbytes(16), rng.randbytes(16)


def connection(seed: int, pc_key: bytes = SITE_KEY) -> tuple[LinkAuth, LinkAuth]:
    nc, np_ = nonces(seed)
    return LinkAuth(SITE_KEY, CONTROLLER, nc), LinkAuth(pc_key, PC, np_)


def run(controller: LinkAuth, pc: LinkAuth) -> tuple[dict, dict]:
    """HELLO, AUTH, AUTH_OK between the two: (the AUTH's fields, the AUTH_OK's)."""
    assert pc.on_hello(controller.nonce) is None
    auth = pc.answer()
    assert controller.on_auth(**auth) is None
    auth_ok = controller.answer()
    assert pc.on_auth_ok(**auth_ok) is None
    return auth, auth_ok


def test_the_handshake_runs_through_its_phases_and_both_sides_agree_on_the_keys():
    controller, pc = connection(1)
    assert (controller.phase, pc.phase) == (Phase.AWAIT_AUTH, Phase.AWAIT_HELLO)
    assert pc.on_hello(controller.nonce) is None and pc.phase is Phase.HELLO
    auth = pc.answer()
    assert pc.phase is Phase.AWAIT_PROOF and not pc.established and pc.send_key is None
    assert controller.on_auth(**auth) is None and controller.phase is Phase.PROVEN
    assert not controller.established and controller.send_key is None   # AUTH_OK first
    auth_ok = controller.answer()
    assert controller.established
    assert pc.on_auth_ok(**auth_ok) is None and pc.established
    assert controller.send_key == pc.receive_key and pc.send_key == controller.receive_key
    assert controller.send_key != controller.receive_key
    other_controller, other_pc = connection(2)
    run(other_controller, other_pc)
    assert other_pc.send_key != pc.send_key            # keys per connection


@pytest.mark.parametrize('seed', range(50))
def test_an_auth_from_an_earlier_connection_is_refused_and_changes_nothing(seed):
    """The replayer holds the AUTH (and the AUTH_OK) of an earlier connection, no key."""
    recorded, _ = run(*connection(2 * seed))
    controller, pc = connection(2 * seed + 1)
    refusal = controller.on_auth(**recorded)
    assert 'does not match' in refusal
    assert controller.phase is Phase.AWAIT_AUTH and not controller.established
    run(controller, pc)                                # the genuine PC still gets in


@pytest.mark.parametrize('seed', range(50))
def test_a_keyless_controller_replaying_a_recorded_handshake_never_gets_trusted(seed):
    """Recorded HELLO (old Nc) and AUTH_OK: the PC's fresh Np makes the old proof worthless."""
    old_controller, old_pc = connection(2 * seed)
    _, recorded_ok = run(old_controller, old_pc)
    _, pc = connection(2 * seed + 1)
    assert pc.on_hello(old_controller.nonce) is None   # a HELLO proves nothing ...
    pc.answer()
    assert 'does not match' in pc.on_auth_ok(**recorded_ok)   # ... and its AUTH_OK fails
    assert pc.phase is Phase.AWAIT_PROOF and pc.receive_key is None
    assert 'out of phase' in pc.on_hello(old_controller.nonce)  # replayed HELLO


def test_the_wrong_site_key_is_refused_at_each_end():
    controller, pc = connection(3, pc_key=bytes(KEY_BYTES))
    assert pc.on_hello(controller.nonce) is None
    assert 'does not match' in controller.on_auth(**pc.answer())
    honest_controller, keyless_pc = connection(4)
    impostor = LinkAuth(bytes(KEY_BYTES), CONTROLLER, honest_controller.nonce)
    assert keyless_pc.on_hello(impostor.nonce) is None
    impostor_auth = keyless_pc.answer()
    assert 'does not match' in impostor.on_auth(**impostor_auth)


def test_reflected_handshake_frames_and_swapped_proofs_are_refused():
    controller, pc = connection(5)
    assert 'reflected' in controller.on_hello(controller.nonce)       # its own HELLO
    assert pc.on_hello(controller.nonce) is None
    auth = pc.answer()
    assert 'reflected' in pc.on_auth(**auth)                          # its own AUTH
    assert controller.on_auth(**auth) is None
    auth_ok = controller.answer()
    assert 'reflected' in controller.on_auth_ok(**auth_ok)            # its own AUTH_OK
    twin_controller, twin_pc = connection(5)
    assert twin_pc.on_hello(twin_controller.nonce) is None
    twin_pc.answer()
    assert 'does not match' in twin_pc.on_auth_ok(proof=auth['proof'])   # P_pc as P_c
    assert 'does not match' in twin_controller.on_auth(nonce=pc.nonce, proof=auth_ok['proof'])


def test_handshake_frames_out_of_phase_are_refused():
    controller, pc = connection(6)
    assert 'out of phase' in pc.on_auth_ok(proof=bytes(16))         # before any HELLO
    with pytest.raises(ValueError, match='nothing to answer'):
        pc.answer()
    auth, auth_ok = run(controller, pc)
    assert 'out of phase' in controller.on_auth(**auth)              # the same AUTH again
    assert 'out of phase' in pc.on_auth_ok(**auth_ok)
    assert 'out of phase' in pc.on_hello(controller.nonce)
    with pytest.raises(ValueError, match='nothing to answer'):
        controller.answer()


def test_through_the_codec_only_session_frames_are_authenticated():
    """Handshake frames and a pre-session ERROR decode but never count as authenticated; a
    session frame in the same read right behind AUTH_OK passes; after the session an ERROR
    needs the session tag."""
    controller, pc = connection(7)
    to_pc, to_controller = proto.Encoder(controller), proto.Encoder(pc)
    at_pc, at_controller = proto.Decoder(pc), proto.Decoder(controller)
    assert to_pc.encode(proto.JOINT_STATE, **STATE) is None          # nothing before AUTH
    busy = to_pc.encode(proto.ERROR, code=proto.E_BUSY, text='another PC is connected')
    hello = to_pc.encode(proto.HELLO, version=proto.AUTH_VERSION, names=NAMES,
                         nonce=controller.nonce)
    frames, errors = at_pc.feed(busy + hello)
    assert errors == [] and [(f.type, f.authenticated) for f in frames] == [
        (proto.ERROR, False), (proto.HELLO, False)]
    assert to_controller.encode(proto.HEARTBEAT, time=0.0) is None   # nothing before AUTH_OK
    frames, _ = at_controller.feed(to_controller.encode(proto.AUTH, **pc.answer()))
    assert [(f.type, f.authenticated) for f in frames] == [(proto.AUTH, False)]
    stream = (to_pc.encode(proto.AUTH_OK, **controller.answer())
              + to_pc.encode(proto.JOINT_STATE, **STATE))
    frames, errors = at_pc.feed(stream)
    assert errors == [] and [(f.type, f.authenticated) for f in frames] == [
        (proto.AUTH_OK, False), (proto.JOINT_STATE, True)]
    frames, errors = at_pc.feed(busy)                                  # open ERROR: refused
    assert frames == [] and 'tag mismatch' in errors[0]
    frames, _ = at_pc.feed(to_pc.encode(proto.ERROR, code=proto.E_STATE, text='not ready'))
    assert [(f.type, f.authenticated) for f in frames] == [(proto.ERROR, True)]
    frames, errors = at_pc.feed(hello)                                 # HELLO replayed
    assert frames == [] and 'out of phase' in errors[0]
    assert at_pc.rejected == 2


def test_version_2_frames_are_refused_as_withdrawn_and_skipped_whole():
    controller, pc = connection(8)
    run(controller, pc)
    legacy = bytearray(proto.encode(proto.HEARTBEAT, 3, pc.send_key, time=1.0))
    legacy[2] = 2
    good = proto.encode(proto.HEARTBEAT, 4, pc.send_key, time=2.0)
    frames, errors = proto.Decoder(controller).feed(bytes(legacy) + good)
    assert [f.seq for f in frames] == [4] and len(errors) == 1 and 'withdrawn' in errors[0]
    frames, errors = proto.Decoder().feed(bytes(legacy))
    assert frames == [] and 'withdrawn' in errors[0]


def test_a_plain_link_refuses_auth_frames():
    frames, errors = proto.Decoder().feed(proto.encode(proto.AUTH, 1, nonce=bytes(16),
                                                       proof=bytes(16)))
    assert frames == [] and 'no handshake' in errors[0]
