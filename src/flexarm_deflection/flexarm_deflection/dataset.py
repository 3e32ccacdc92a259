"""Crash-safe, append-only dataset of deflection samples (JSON Lines with a CRC per record).

File format (UTF-8 text, one JSON object per line, ``\\n``-terminated):

- line 1, the header::

    {"format": "flexarm-deflection-dataset", "version": 1, "created": "<ISO 8601 UTC>",
     "schema": {"stamp": "s", "joints": "rad, m, rad, rad", ...}}

- every further line, one sample and the CRC-32 (8 lowercase hex digits) of its canonical
  JSON (``json.dumps(sample, sort_keys=True, separators=(",", ":"))`` encoded as UTF-8)::

    {"crc32": "1c291ca3", "sample": {"deflection": [dx, dy, dphi], "holes_used": 7,
     "joints": [t1, t2, t3, t4], "measured_pose": [x, y, phi], "payload": 0.0,
     "residual": 2e-05, "rigid_pose": [x, y, phi], "stamp": 1700000000.5}}

  SI units: m, rad, kg, s; deflection = measured_pose − rigid_pose (φ wrapped).

Durability: :class:`DatasetWriter` appends each record with a single ``write`` followed by
``flush`` and ``os.fsync``; when it creates the file it fsyncs the header and the directory.
A sample is on disk when :meth:`DatasetWriter.append` returns. A crash (``kill -9``, power
loss) can at worst leave the last line partly written: :func:`load_dataset` skips and counts
lines that are truncated (no final newline), not JSON, or whose CRC does not match, and never
raises on them. Re-opening a file whose last line is partial first terminates that line, so
new records are never glued onto it; a header cut short at creation is rewritten.

:attr:`Dataset.hash` is the SHA-256 of the canonical sample JSONs joined by ``\\n``: the
same samples in the same order give the same hash, whatever file they came from.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import zlib
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any

import numpy as np

FORMAT = 'flexarm-deflection-dataset'
VERSION = 1
SCHEMA = {
    'stamp': 's', 'joints': 'rad, m, rad, rad', 'payload': 'kg', 'rigid_pose': 'm, m, rad',
    'measured_pose': 'm, m, rad', 'deflection': 'm, m, rad (measured - rigid)',
    'holes_used': 'count', 'residual': 'm', 'motion': 'id of the arm claim it was taken in'}
OPTIONAL = {'motion'}      # absent from records written before it was kept
_HEADER_START = json.dumps({'format': FORMAT})[:-1].encode()


@dataclass(frozen=True)
class Sample:
    """One learning pair, as ``flexarm_msgs/DeflectionSample`` (poses as (x, y, φ))."""

    stamp: float
    joints: tuple[float, float, float, float]
    payload: float
    rigid_pose: tuple[float, float, float]
    measured_pose: tuple[float, float, float]
    deflection: tuple[float, float, float]
    holes_used: int
    residual: float
    motion: str = ''       # the arm's claim it was taken in: the arm held by it alone

    def __post_init__(self) -> None:
        for name, size in (('joints', 4), ('rigid_pose', 3), ('measured_pose', 3),
                           ('deflection', 3)):
            values = tuple(float(v) for v in np.asarray(getattr(self, name)).reshape(-1))
            if len(values) != size:
                raise ValueError(f'sample {name} needs {size} values, got {len(values)}')
            object.__setattr__(self, name, values)
        for name in ('stamp', 'payload', 'residual'):
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, 'holes_used', int(self.holes_used))
        if not all(math.isfinite(v) for v in self._numbers()):
            raise ValueError('sample contains NaN or infinite values')

    def _numbers(self) -> tuple[float, ...]:
        return (self.stamp, *self.joints, self.payload, *self.rigid_pose, *self.measured_pose,
                *self.deflection, self.residual)

    def as_dict(self) -> dict[str, Any]:
        """The record's fields; ``motion`` only when known (a record of before it was kept
        keeps its CRC and hash)."""
        return {name: list(value) if isinstance(value, tuple) else value
                for name, value in self.__dict__.items() if name != 'motion' or value}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Sample:
        return cls(**{name: d[name] for name in SCHEMA if name in d or name not in OPTIONAL})


def _canonical(sample: Sample) -> bytes:
    return json.dumps(sample.as_dict(), sort_keys=True, separators=(',', ':'),
                      allow_nan=False).encode()


def _record_line(sample: Sample) -> bytes:
    body = _canonical(sample)
    crc = f'{zlib.crc32(body):08x}'.encode()
    return b'{"crc32":"' + crc + b'","sample":' + body + b'}\n'


def _fsync_directory(directory: Path) -> None:
    fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _is_cut_header(line: bytes) -> bool:
    """Whether a first line is empty or a header cut short by a crash at file creation."""
    return not line.endswith(b'\n') and _HEADER_START.startswith(line[:len(_HEADER_START)])


def _check_header(line: bytes, path: Path) -> None:
    """ValueError unless ``line`` is a complete header of a supported version."""
    try:
        header = json.loads(line)
    except ValueError:
        header = None
    if not (line.endswith(b'\n') and isinstance(header, dict)
            and header.get('format') == FORMAT):
        raise ValueError(f'{path} is not a {FORMAT} file (bad header)')
    version = header.get('version')
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ValueError(f'{path}: the {FORMAT} header has no valid version ({version!r})')
    if version > VERSION:
        raise ValueError(f'{path}: dataset version {version} is newer than the '
                         f'supported {VERSION}')


class DatasetWriter:
    """Appends samples durably to a dataset file, creating it (and its directory) if needed."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file: IO[bytes] = open(self.path, 'a+b')
        try:
            self._prepare()
        except BaseException:
            self._file.close()
            raise

    def _prepare(self) -> None:
        self._file.seek(0)
        first = self._file.readline()
        if _is_cut_header(first):
            self._file.truncate(0)   # new file, or a header cut short at its creation
            header = {'format': FORMAT, 'version': VERSION,
                      'created': datetime.now(UTC).isoformat(), 'schema': SCHEMA}
            self._write(json.dumps(header).encode() + b'\n')
            _fsync_directory(self.path.parent)
            return
        _check_header(first, self.path)
        self._file.seek(-1, os.SEEK_END)
        if self._file.read(1) != b'\n':
            self._write(b'\n')   # terminate a partial last record; load skips it

    def _write(self, data: bytes) -> None:
        self._file.write(data)
        self._file.flush()
        os.fsync(self._file.fileno())

    def append(self, sample: Sample) -> None:
        """Write one sample; it is on disk (fsynced) when this returns."""
        self._write(_record_line(sample))

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> DatasetWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass
class Dataset:
    """Samples in file order, and the line numbers (1-based) that were skipped on load."""

    samples: list[Sample]
    skipped_lines: list[int] = field(default_factory=list)
    path: Path | None = None

    @property
    def skipped(self) -> int:
        """Number of truncated or corrupt records that were ignored."""
        return len(self.skipped_lines)

    def __len__(self) -> int:
        return len(self.samples)

    @property
    def hash(self) -> str:
        """SHA-256 hex of the canonical samples (see module docstring)."""
        return hashlib.sha256(b'\n'.join(_canonical(s) for s in self.samples)).hexdigest()

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """joints (N, 4), deflections (N, 3) [m, m, rad] and payload (N,) [kg]."""
        joints = np.array([s.joints for s in self.samples], dtype=float).reshape(-1, 4)
        deflections = np.array([s.deflection for s in self.samples], dtype=float).reshape(-1, 3)
        return joints, deflections, np.array([s.payload for s in self.samples], dtype=float)


def _parse_record(line: bytes) -> Sample | None:
    """The sample of a complete record line, or None when it is truncated or corrupt."""
    if not line.endswith(b'\n'):
        return None
    try:
        record = json.loads(line)
        sample = Sample.from_dict(record['sample'])
        ok = record['crc32'] == f'{zlib.crc32(_canonical(sample)):08x}'
    except (ValueError, TypeError, KeyError, OverflowError):   # e.g. int(1e999): overflow
        return None
    return sample if ok else None


def load_dataset(path: str | Path) -> Dataset:
    """All intact samples of a dataset file; bad records are skipped and counted.

    An empty file or a partly written header (a crash at creation) gives an empty dataset;
    a file that is not a dataset, or of a newer version, raises ValueError.
    """
    path = Path(path)
    with open(path, 'rb') as file:
        lines = file.readlines()
    if not lines or _is_cut_header(lines[0]):
        return Dataset([], [1] if lines else [], path)
    _check_header(lines[0], path)
    samples, skipped = [], []
    for number, line in enumerate(lines[1:], start=2):
        sample = _parse_record(line)
        if sample is None:
            if line.strip():
                skipped.append(number)
        else:
            samples.append(sample)
    return Dataset(samples, skipped, path)


def dataset_name_error(name: str) -> str | None:
    """Why ``name`` cannot name a dataset in the data directory (e.g. '../x'), or None."""
    if name and not name.replace('-', '').replace('_', '').isalnum():
        return f'dataset name "{name}" must be letters, digits, - and _'
    return None
