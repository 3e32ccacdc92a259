"""The payload the arm carries, kept across restarts of the learner that declares it.

The arm does not drop its tool because a node restarted (``restart: true`` after a crash, or a
graph brought up again): a learner that came back announcing its configured payload would make
the compensator plan for the wrong load and store the next samples under it (and the simulator,
which follows ``/payload``, would put the tool down). So every declaration (``flexarm payload
KG``, ``flexarm collect --payload KG``) is written atomically to ``<model directory>/payload.json``
beside ``current.json`` (the directory is per arm), and a starting learner takes the stored value
over its configured ``payload``. ``flexarm payload 0`` declares the tool put down. A record that
does not read as ``{"payload": <finite kg >= 0>}`` counts as none, with its reason.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from flexarm_core.atomic_file import atomic_write

PAYLOAD = 'payload.json'


def payload_path(model_dir: Path) -> Path:
    return Path(model_dir) / PAYLOAD


def read_payload(model_dir: Path) -> float | None:
    """The last declared payload [kg], or None when none was stored; ValueError (with the
    file and the reason) when the record is damaged."""
    path = payload_path(model_dir)
    try:
        value = json.loads(path.read_text())['payload']
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f'{path} is damaged ({type(exc).__name__}: {exc})') from exc
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and value >= 0):
        raise ValueError(f'{path} is damaged (payload {value!r} is not a finite number >= 0 kg)')
    return float(value)


def write_payload(model_dir: Path, kg: float) -> None:
    """Store the declared payload [kg]; a crash leaves the previous declaration or this one."""
    atomic_write(payload_path(model_dir), lambda f: f.write(json.dumps({'payload': kg}).encode()))
