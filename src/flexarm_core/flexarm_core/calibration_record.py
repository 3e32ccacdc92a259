"""A site calibration file (pure): a correction, as a list under its key, with how it was
found. The tool calibration and the camera calibration are kept this way."""
from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from flexarm_core.atomic_file import atomic_write


def read_record(path: str | Path, key: str, parse: Callable[[Sequence[float]], Any],
                what: str, command: str) -> dict[str, Any] | None:
    """The record at ``path`` with ``correction`` parsed from ``record[key]``, None if there is
    none; ValueError naming the file (``what`` it is) and the ``command`` that makes it again
    if it is damaged."""
    path = Path(path)
    if not path.exists():
        return None
    try:
        record = json.loads(path.read_text(encoding='utf-8'))
        record['correction'] = parse(record[key])
    except (ValueError, KeyError, TypeError) as exc:
        raise ValueError(f'{what} {path} is damaged ({exc}); run {command} again') from exc
    return record


def write_record(path: str | Path, key: str, values: list[float], **details: Any) -> None:
    """Store ``values`` under ``key`` with ``details`` (how they were found), atomically."""
    record = {key: values, **details}
    atomic_write(path, lambda f: f.write(json.dumps(record, indent=1).encode() + b'\n'))
