"""The learner's model directory: which model is current, and the next version number.

``current.json`` names the model the learner announces. It is written atomically, but a user
may still edit or truncate it by hand: a record that does not read as
``{"version": "<int>", "kind": str, "path": str}`` counts as no record (the learner starts
without announcing a model and says why, naming the file, the reason and the versions still on
disk: "no model" would send the operator to train again when ``flexarm model use`` would do),
never as a crash. Version numbers only grow: the next
one is past the current record and past every ``*-v<N>.model`` file in the directory, so a lost
or damaged record can never make a new model overwrite an older one.

Provenance: a model file's metadata holds, besides its metrics, ``provenance``: the dataset it
was trained on, the distinct payloads of its samples and ``arm``, a fingerprint of the arm
configuration (config/arm.yaml as the learner loaded it). :func:`fit_warning` says why a model
may not fit the arm as configured now, :func:`payload_warning` the payload it carries now;
:func:`list_models` is ``flexarm model list``.
"""
from __future__ import annotations

import hashlib
import json
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from flexarm_core.atomic_file import atomic_write

CURRENT = 'current.json'
_MODEL_VERSION = re.compile(r'-v(\d+)\.model$')


class DamagedRecord(ValueError):
    """``current.json`` exists but is not a valid record (the message: :func:`damaged_text`)."""


def versions_on_disk(model_dir: Path) -> list[int]:
    """Versions of the ``*-v<N>.model`` files in ``model_dir``, ascending."""
    return sorted({int(m.group(1)) for p in Path(model_dir).glob('*.model')
                   if (m := _MODEL_VERSION.search(p.name))})


def damaged_text(what: str, reason: str, versions: Sequence[int]) -> str:
    """'<what> is damaged (<reason>); versions on disk: v1, v2 (...)': what is broken, and
    what the operator can make current instead of training again."""
    if not versions:
        return f'{what} is damaged ({reason}); no model files on disk: collect and train'
    listed = ', '.join(f'v{v}' for v in versions)
    return (f'{what} is damaged ({reason}); versions on disk: {listed} (`flexarm model use '
            f'{versions[-1]}` makes one current)')


def read_current(model_dir: Path) -> dict | None:
    """The current-model record, or None when there is none; DamagedRecord when unreadable."""
    path = Path(model_dir) / CURRENT
    try:
        record = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:
        raise DamagedRecord(damaged_text(str(path), str(exc), versions_on_disk(model_dir))
                            ) from exc
    if not (isinstance(record, dict)
            and all(isinstance(record.get(key), str) for key in ('version', 'kind', 'path'))
            and record['version'].isdecimal()):
        raise DamagedRecord(damaged_text(str(path), 'not a record of version, kind and path',
                                         versions_on_disk(model_dir)))
    return record


def unloadable_text(model_dir: Path, record: dict, reason: str) -> str:
    """Why the model ``record`` (of ``current.json``) names cannot be announced, with the
    versions on disk."""
    return damaged_text(f'{Path(model_dir) / CURRENT}: its model v{record["version"]} '
                        f'({record["path"]})', reason, versions_on_disk(model_dir))


def write_current(model_dir: Path, version: int, kind: str, path: str,
                  dataset_hash: str) -> None:
    record = {'version': str(version), 'kind': kind, 'path': path, 'dataset_hash': dataset_hash}
    atomic_write(Path(model_dir) / CURRENT, lambda f: f.write(json.dumps(record).encode()))


def next_version(model_dir: Path) -> int:
    """One past the highest version in the record or in the model files' names."""
    versions = versions_on_disk(model_dir)
    try:
        current = read_current(model_dir)
    except DamagedRecord:
        current = None
    if current is not None:
        versions.append(int(current['version']))
    return max(versions, default=0) + 1


def arm_fingerprint(arm: dict[str, Any]) -> str:
    """A short hash of an arm configuration tree: equal configurations, equal fingerprints."""
    return hashlib.sha256(json.dumps(arm, sort_keys=True).encode()).hexdigest()[:16]


def provenance(dataset: str, payloads: list[float], arm: str) -> dict[str, Any]:
    """The ``provenance`` entry of a model's metadata."""
    return {'dataset': dataset, 'payloads': sorted({round(float(p), 6) for p in payloads}),
            'arm': arm}


def fit_warning(metadata: dict[str, Any], arm: str) -> str:
    """Why a model may not fit an arm of fingerprint ``arm`` ('' if no reason is known); the
    payload is checked at every goal (:func:`payload_warning`), as it changes at run time."""
    origin = metadata.get('provenance')
    if not isinstance(origin, dict):
        return 'trained before models recorded their dataset, payload and arm configuration'
    if origin.get('arm') != arm:
        return 'trained for another arm configuration (config/arm.yaml differs)'
    return ''


def payload_warning(payloads: Sequence[float], payload_input: bool, payload: float) -> str:
    """Why a model trained at ``payloads`` [kg] may miss with the arm carrying ``payload``:
    a model without the payload input must have been trained at it, one with it within the
    range it was trained over ('' if it fits)."""
    if not payloads:
        return ''
    listed = ', '.join(f'{p:g}' for p in payloads)
    if payload_input:
        if min(payloads) - 1e-6 <= payload <= max(payloads) + 1e-6:
            return ''
        return (f'the arm carries {payload:g} kg, outside the payloads {listed} kg the model '
                'was trained over (extrapolated)')
    if any(math.isclose(p, payload, abs_tol=1e-6) for p in payloads):
        return ''
    return (f'trained at payload {listed} kg, the arm carries {payload:g} kg now: collect at '
            'this payload (`flexarm collect N --payload KG`) and train')


@dataclass(frozen=True)
class ModelEntry:
    """One model file of a model directory, as ``flexarm model list`` shows it."""

    version: int
    path: Path
    current: bool
    metadata: dict[str, Any] | None     # None: the file cannot be read (see ``problem``)
    problem: str = ''


def list_models(model_dir: Path, read: Callable[[Path], dict[str, Any]]) -> list[ModelEntry]:
    """The ``*-v<N>.model`` files of ``model_dir`` by version; ``read(path)`` gives a file's
    metadata (ValueError/OSError for a damaged one, reported as its ``problem``)."""
    try:
        current = read_current(model_dir)
    except DamagedRecord:
        current = None
    entries = []
    for path in Path(model_dir).glob('*.model'):
        match = _MODEL_VERSION.search(path.name)
        if not match:
            continue
        version = int(match.group(1))
        is_current = current is not None and current['version'] == str(version)
        try:
            entries.append(ModelEntry(version, path, is_current, read(path)))
        except (OSError, ValueError) as exc:
            entries.append(ModelEntry(version, path, is_current, None, str(exc)))
    return sorted(entries, key=lambda e: e.version)


def find_model(model_dir: Path, version: str) -> Path:
    """The model file of ``version``; ValueError if there is none (or several)."""
    if not version.isdecimal():
        raise ValueError(f'model version must be a number, not {version!r}')
    found = [p for p in Path(model_dir).glob(f'*-v{int(version)}.model')
             if _MODEL_VERSION.search(p.name)]
    if len(found) != 1:
        raise ValueError(f'no model version {version} in {model_dir}' if not found else
                         f'{len(found)} files of version {version} in {model_dir}')
    return found[0]
