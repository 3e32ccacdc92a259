"""Authentication of the controller link: a per-site key, HMAC-SHA256 over every frame (pure).

Why HMAC and not mutual TLS: both ends already share a site (a key file put on the PC and the
controller by whoever commissions them) and the frames are small and frequent; an HMAC per frame
needs no certificate authority, no expiry handling and nothing outside Python's standard
library, and a controller vendor can implement it in a few lines. What it does not give is
confidentiality: joint angles travel in clear (they are not secret; that they are authentic and
fresh is what matters). The scheme, as PROTOCOL.md ("Authentication") specifies it:

* the controller's HELLO carries a fresh 16-byte nonce ``Nc``, the PC answers with AUTH carrying
  its own nonce ``Np``; both frames are tagged with a handshake key derived from the site key;
* every later frame is tagged with a session key per direction, derived from the site key and
  both nonces, so a frame recorded in one connection is worthless in another and a frame sent by
  one side cannot be reflected back to it;
* within a connection, sequence numbers must increase: a replayed or reordered frame is refused.
"""
from __future__ import annotations

import hashlib
import hmac
import ipaddress
import os
import secrets
import socket
import stat
from pathlib import Path

from flexarm_control.atomic_file import atomic_write

KEY_BYTES = 32          # site key length written by make_key; load_key accepts no less
NONCE_SIZE = 16
TAG_SIZE = 16           # HMAC-SHA256 truncated to 128 bits
PC, CONTROLLER = 'pc', 'controller'


def tag(key: bytes, data: bytes) -> bytes:
    """Authentication tag of ``data``."""
    return hmac.new(key, data, hashlib.sha256).digest()[:TAG_SIZE]


def _derive(site_key: bytes, label: bytes, *parts: bytes) -> bytes:
    return hmac.new(site_key, b'flexarm link/' + label + b''.join(parts), hashlib.sha256).digest()


class LinkAuth:
    """One side's authentication state for one connection (make a new one per connection)."""

    def __init__(self, site_key: bytes, role: str) -> None:
        if role not in (PC, CONTROLLER):
            raise ValueError(f'role must be {PC!r} or {CONTROLLER!r}, not {role!r}')
        self.role = role
        self.nonce = secrets.token_bytes(NONCE_SIZE)
        self._site_key = site_key
        self._handshake_key = _derive(site_key, b'handshake')
        self._send_key: bytes | None = None
        self._receive_key: bytes | None = None
        self._last_received = 0

    @property
    def established(self) -> bool:
        return self._send_key is not None

    def start_session(self, peer_nonce: bytes) -> None:
        """Derive the session keys once the peer's nonce is known (HELLO or AUTH received)."""
        if self.established:
            raise ValueError('session already established on this connection')
        if len(peer_nonce) != NONCE_SIZE:
            raise ValueError(f'nonce of {len(peer_nonce)} bytes, need {NONCE_SIZE}')
        nonces = (peer_nonce + self.nonce if self.role == PC else self.nonce + peer_nonce)
        to_pc = _derive(self._site_key, b'controller->pc', nonces)
        to_controller = _derive(self._site_key, b'pc->controller', nonces)
        self._send_key, self._receive_key = ((to_pc, to_controller) if self.role == CONTROLLER
                                             else (to_controller, to_pc))

    def sending_key(self, handshake: bool) -> bytes | None:
        """Key to tag an outgoing frame with; None before the session for session frames."""
        return self._handshake_key if handshake else self._send_key

    def receiving_key(self, handshake: bool) -> bytes | None:
        """Key an incoming frame must be tagged with; None: it cannot be accepted yet."""
        return self._handshake_key if handshake else self._receive_key

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
