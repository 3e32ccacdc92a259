"""The learner's model directory: which model is current, and the next version number.

``current.json`` names the model the learner announces. It is written atomically, but a user
may still edit or truncate it by hand: a record that does not read as
``{"version": "<int>", "kind": str, "path": str}`` counts as no record (the learner starts
without announcing a model and says why), never as a crash. Version numbers only grow: the next
one is past the current record and past every ``*-v<N>.model`` file in the directory, so a lost
or damaged record can never make a new model overwrite an older one.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

from flexarm_control.atomic_file import atomic_write

CURRENT = 'current.json'
_MODEL_VERSION = re.compile(r'-v(\d+)\.model$')


class DamagedRecord(ValueError):
    """``current.json`` exists but is not a valid record."""


def read_current(model_dir: Path) -> dict | None:
    """The current-model record, or None when there is none; DamagedRecord when unreadable."""
    path = Path(model_dir) / CURRENT
    try:
        record = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:
        raise DamagedRecord(f'{path}: {exc}') from exc
    if not (isinstance(record, dict)
            and all(isinstance(record.get(key), str) for key in ('version', 'kind', 'path'))
            and record['version'].isdecimal()):
        raise DamagedRecord(f'{path}: not a record of version, kind and path')
    return record


def write_current(model_dir: Path, version: int, kind: str, path: str,
                  dataset_hash: str) -> None:
    record = {'version': str(version), 'kind': kind, 'path': path, 'dataset_hash': dataset_hash}
    atomic_write(Path(model_dir) / CURRENT, lambda f: f.write(json.dumps(record).encode()))


def next_version(model_dir: Path) -> int:
    """One past the highest version in the record or in the model files' names."""
    versions = [int(m.group(1)) for p in Path(model_dir).glob('*.model')
                if (m := _MODEL_VERSION.search(p.name))]
    try:
        current = read_current(model_dir)
    except DamagedRecord:
        current = None
    if current is not None:
        versions.append(int(current['version']))
    return max(versions, default=0) + 1
