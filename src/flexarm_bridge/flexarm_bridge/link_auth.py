"""Authentication of the controller link (protocol version 3, pure): a per-site key, a mutual
challenge-response over fresh nonces of both sides, then an HMAC-SHA256 tag on every frame.

Why HMAC and not mutual TLS: both ends already share a site (a key file put on the PC and the
controller by whoever commissions them) and the frames are small and frequent; HMAC needs no
certificate authority, no expiry handling and nothing outside Python's standard library, and a
controller vendor can implement it in a few lines. What it does not give is confidentiality:
joint angles travel in clear (they are not secret; that they are authentic and fresh is what
matters). The scheme, as PROTOCOL.md ("Authentication") specifies it:

* the controller's HELLO carries its fresh nonce ``Nc``; the PC answers with AUTH carrying its
  fresh nonce ``Np`` and a proof over both under the site key; the controller answers with
  AUTH_OK carrying its own proof over both. Each side trusts the other only once it verified a
  proof bound to its *own* fresh nonce, so no frame recorded in another connection stands in
  for a proof (version 2 accepted recorded handshake frames);
* the handshake frames prove nothing by themselves (their trailer is a public checksum):
  replaying or reflecting them gets the sender nowhere, and they never count as a sign of life;
* every later frame is tagged with a session key per direction derived from both nonces, so a
  frame recorded in one connection is worthless in another and one sent by a side cannot be
  reflected back to it; within a connection sequence numbers must increase.
"""
from __future__ import annotations

import enum
import hashlib
import hmac
import ipaddress
import os
import secrets
import socket
import stat
from pathlib import Path

from flexarm_core.atomic_file import atomic_write

KEY_BYTES = 32          # site key length written by make_key; load_key accepts no less
NONCE_SIZE = 16
TAG_SIZE = 16           # HMAC-SHA256 truncated to 128 bits: frame tags and handshake proofs
PC, CONTROLLER = 'pc', 'controller'
# Key of the checksum on handshake frames and pre-session ERRORs: public, so it proves nothing
# (those frames are taken for what they say, never for who sent them).
OPEN_KEY = b'flexarm link v3/open'


class Phase(enum.Enum):
    """Where one side of a connection is in the handshake."""
    AWAIT_HELLO = 'waiting for HELLO'          # PC
    HELLO = 'HELLO received, not answered'     # PC
    AWAIT_AUTH = 'waiting for AUTH'            # controller
    AWAIT_PROOF = 'waiting for AUTH_OK'        # PC
    PROVEN = 'AUTH verified, AUTH_OK not sent'  # controller
    SESSION = 'session'                        # both


def tag(key: bytes, data: bytes) -> bytes:
    """Authentication tag (or, under :data:`OPEN_KEY`, checksum) of ``data``."""
    return hmac.new(key, data, hashlib.sha256).digest()[:TAG_SIZE]


def _derive(site_key: bytes, label: bytes, *parts: bytes) -> bytes:
    return hmac.new(site_key, b'flexarm link v3/' + label + b''.join(parts),
                    hashlib.sha256).digest()


class LinkAuth:
    """One side's handshake and session for one connection (make a new one per connection).

    The frames' parts go in through ``on_hello`` / ``on_auth`` / ``on_auth_ok`` (each returns
    None when taken, else why it is refused, and a refusal changes nothing) and come out of
    :meth:`answer`. ``nonce`` is drawn fresh unless given (test vectors).
    """

    def __init__(self, site_key: bytes, role: str, nonce: bytes | None = None) -> None:
        if role not in (PC, CONTROLLER):
            raise ValueError(f'role must be {PC!r} or {CONTROLLER!r}, not {role!r}')
        self.role = role
        self.nonce = secrets.token_bytes(NONCE_SIZE) if nonce is None else nonce
        if len(self.nonce) != NONCE_SIZE:
            raise ValueError(f'nonce of {len(self.nonce)} bytes, need {NONCE_SIZE}')
        self.phase = Phase.AWAIT_AUTH if role == CONTROLLER else Phase.AWAIT_HELLO
        self._site_key = site_key
        self._peer_nonce = b''
        self._keys: tuple[bytes, bytes] | None = None   # session keys (send, receive)
        self._last_received = 0

    @property
    def established(self) -> bool:
        """Whether the session runs: both proofs exchanged, session frames go both ways."""
        return self.phase is Phase.SESSION

    @property
    def send_key(self) -> bytes | None:
        """Session key of this side's frames; None before the session."""
        return self._keys[0] if self.established else None

    @property
    def receive_key(self) -> bytes | None:
        """Session key of the peer's frames; None before the session."""
        return self._keys[1] if self.established else None

    def _nonces(self) -> tuple[bytes, bytes]:
        """(Nc, Np)."""
        return ((self.nonce, self._peer_nonce) if self.role == CONTROLLER
                else (self._peer_nonce, self.nonce))

    def _proof(self, of: str) -> bytes:
        """The proof ``of`` one side (PC: over Nc ‖ Np, controller: over Np ‖ Nc)."""
        nc, np_ = self._nonces()
        if of == PC:
            return _derive(self._site_key, b'pc proof', nc, np_)[:TAG_SIZE]
        return _derive(self._site_key, b'controller proof', np_, nc)[:TAG_SIZE]

    def _derive_session(self) -> None:
        nc, np_ = self._nonces()
        to_pc = _derive(self._site_key, b'controller->pc', nc, np_)
        to_controller = _derive(self._site_key, b'pc->controller', nc, np_)
        self._keys = ((to_pc, to_controller) if self.role == CONTROLLER
                      else (to_controller, to_pc))

    def _refusal(self, frame: str, expected_role: str, phase: Phase) -> str | None:
        if self.role != expected_role:
            return f'{frame} refused: a {self.role} never receives one (reflected?)'
        if self.phase is not phase:
            return f'{frame} refused: out of phase ({self.phase.value})'
        return None

    def on_hello(self, controller_nonce: bytes) -> str | None:
        """PC: the controller's HELLO (its nonce proves nothing yet)."""
        refusal = self._refusal('HELLO', PC, Phase.AWAIT_HELLO)
        if refusal is None:
            self._peer_nonce, self.phase = controller_nonce, Phase.HELLO
        return refusal

    def on_auth(self, nonce: bytes, proof: bytes) -> str | None:
        """Controller: the PC's AUTH, whose proof must be bound to this side's nonce."""
        refusal = self._refusal('AUTH', CONTROLLER, Phase.AWAIT_AUTH)
        if refusal is not None:
            return refusal
        self._peer_nonce = nonce
        if not hmac.compare_digest(proof, self._proof(PC)):
            self._peer_nonce = b''
            return ('AUTH refused: its proof does not match this connection (replayed from '
                    'another one, or made with another site key)')
        self._derive_session()
        self.phase = Phase.PROVEN
        return None

    def on_auth_ok(self, proof: bytes) -> str | None:
        """PC: the controller's AUTH_OK, whose proof must be bound to this side's nonce."""
        refusal = self._refusal('AUTH_OK', PC, Phase.AWAIT_PROOF)
        if refusal is not None:
            return refusal
        if not hmac.compare_digest(proof, self._proof(CONTROLLER)):
            return ('AUTH_OK refused: its proof does not match this connection (replayed, or '
                    'made with another site key)')
        self.phase = Phase.SESSION
        return None

    def answer(self) -> dict[str, bytes]:
        """Fields of this side's next handshake frame: the PC's AUTH after a HELLO, the
        controller's AUTH_OK after a verified AUTH (its session starts with it)."""
        if self.phase is Phase.HELLO:
            self._derive_session()
            self.phase = Phase.AWAIT_PROOF
            return {'nonce': self.nonce, 'proof': self._proof(PC)}
        if self.phase is Phase.PROVEN:
            self.phase = Phase.SESSION
            return {'proof': self._proof(CONTROLLER)}
        raise ValueError(f'nothing to answer: {self.role} {self.phase.value}')

    def fresh(self, seq: int) -> bool:
        """Whether a verified session frame's sequence number is new (and remember it)."""
        if seq <= self._last_received:
            return False
        self._last_received = seq
        return True


def make_key(path: str | Path) -> Path:
    """Write a new random site key (hex) to ``path``, readable by its owner only."""
    path = Path(path)

    def write(file) -> None:
        os.fchmod(file.fileno(), stat.S_IRUSR | stat.S_IWUSR)
        file.write(secrets.token_hex(KEY_BYTES).encode() + b'\n')

    atomic_write(path, write)
    return path


def load_key(path: str | Path) -> bytes:
    """The site key in ``path``; ValueError if it is unreadable, short, or readable by others."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
        text = path.read_text(encoding='ascii').strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f'link key {path}: {exc}') from exc
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise ValueError(f'link key {path} is accessible by other users '
                         f'(mode {stat.S_IMODE(mode):o}); chmod 600 it')
    try:
        key = bytes.fromhex(text)
    except ValueError as exc:
        raise ValueError(f'link key {path} is not hexadecimal') from exc
    if len(key) < KEY_BYTES:
        raise ValueError(f'link key {path} has {len(key)} bytes, need at least {KEY_BYTES}')
    return key


def is_loopback(host: str) -> bool:
    """Whether every address ``host`` stands for is a loopback address ('' and 0.0.0.0 are not)."""
    try:
        infos = socket.getaddrinfo(host or None, None, proto=socket.IPPROTO_TCP,
                                   flags=socket.AI_PASSIVE)
    except socket.gaierror:
        return False
    return all(ipaddress.ip_address(info[4][0].split('%')[0]).is_loopback for info in infos)


def site_key_for(host: str, key_file: str) -> bytes | None:
    """The site key a link to or on ``host`` uses; ValueError if it needs one and has none."""
    if key_file:
        return load_key(key_file)
    if not is_loopback(host):
        raise ValueError(f'{host or "all interfaces"} is not a loopback address: the controller '
                         'link leaves this machine and must be authenticated; set '
                         'link_key_file (make one with `flexarm keygen PATH`, PROTOCOL.md)')
    return None
