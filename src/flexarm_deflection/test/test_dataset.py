"""Crash-safe deflection dataset: round trip, kill -9 while writing, damaged records."""
from __future__ import annotations

import dataclasses
import json
import math
import signal
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import numpy as np
import pytest

from flexarm_deflection.dataset import DatasetWriter, Sample, load_dataset


def sample(i: int) -> Sample:
    """A distinct, plausible sample number ``i``."""
    joints = np.array([0.01 * i, 0.6, -1.0 + 0.003 * i, 0.2])
    rigid = np.array([1.0 + 0.001 * i, 0.2, 0.3])
    deflection = np.array([0.002, -0.012 - 1e-5 * i, 0.01])
    return Sample(stamp=1.7e9 + i / 3, joints=joints, payload=0.5, rigid_pose=rigid,
                  measured_pose=rigid + deflection, deflection=deflection, holes_used=7,
                  residual=2e-5)


def write(path: Path, count: int) -> None:
    with DatasetWriter(path) as writer:
        for i in range(count):
            writer.append(sample(i))


def test_round_trip_and_arrays(tmp_path: Path) -> None:
    path = tmp_path / 'new_dir' / 'samples.jsonl'
    write(path, 5)
    dataset = load_dataset(path)
    assert dataset.samples == [sample(i) for i in range(5)] and dataset.skipped == 0
    joints, deflections, payload = dataset.arrays()
    assert joints.shape == (5, 4) and deflections.shape == (5, 3) and payload.shape == (5,)
    np.testing.assert_array_equal(joints[3], sample(3).joints)
    header = json.loads(path.read_text().splitlines()[0])
    assert header['format'] == 'flexarm-deflection-dataset' and header['version'] == 1
    assert 'deflection' in header['schema']


def test_hash_depends_on_content_only(tmp_path: Path) -> None:
    write(tmp_path / 'a.jsonl', 4)
    write(tmp_path / 'b.jsonl', 4)
    write(tmp_path / 'c.jsonl', 3)
    a, b, c = (load_dataset(tmp_path / f'{n}.jsonl') for n in 'abc')
    assert a.hash == b.hash != c.hash
    assert len(a.hash) == 64


def test_appending_to_an_existing_file(tmp_path: Path) -> None:
    path = tmp_path / 'samples.jsonl'
    write(path, 2)
    with DatasetWriter(path) as writer:
        writer.append(sample(2))
    assert [s.stamp for s in load_dataset(path).samples] == [sample(i).stamp for i in range(3)]
    assert path.read_text().count('flexarm-deflection-dataset') == 1


WRITER = textwrap.dedent('''
    import sys, time
    from flexarm_deflection.dataset import DatasetWriter, Sample

    def half_then_hang(self, data):   # the kill lands in the middle of a record
        self._file.write(data[:len(data) // 2])
        self._file.flush()
        print('mid-record', flush=True)
        time.sleep(60)

    with DatasetWriter(sys.argv[1]) as writer:
        for i in range(int(sys.argv[2])):
            writer.append(Sample(i, [0.1, 0.6, -1.0, i], 0.0, [1, 2, 3], [1, 2, 3], [0, 0, 0],
                                 7, 0.0))
            print(i, flush=True)
        DatasetWriter._write = half_then_hang
        writer.append(Sample(-1, [0, 0, 0, 0], 0, [0, 0, 0], [0, 0, 0], [0, 0, 0], 0, 0))
''')


def test_writer_killed_mid_record_loses_no_completed_sample(tmp_path: Path) -> None:
    path = tmp_path / 'samples.jsonl'
    writer = subprocess.Popen([sys.executable, '-c', WRITER, str(path), '30'],
                              stdout=subprocess.PIPE, text=True)
    watchdog = threading.Timer(30.0, writer.kill)   # bounds the blocking reads below
    watchdog.start()
    try:
        acknowledged = [writer.stdout.readline().strip() for _ in range(31)]
        assert acknowledged == [*map(str, range(30)), 'mid-record']
        writer.send_signal(signal.SIGKILL)
        assert writer.wait(timeout=10) == -signal.SIGKILL
    finally:
        watchdog.cancel()
        if writer.poll() is None:
            writer.kill()
            writer.wait(timeout=10)
        writer.stdout.close()
    assert not path.read_bytes().endswith(b'\n')   # a record was cut short
    dataset = load_dataset(path)
    assert [s.joints[3] for s in dataset.samples] == list(range(30))
    assert dataset.skipped_lines == [32]
    with DatasetWriter(path) as resumed:
        resumed.append(sample(99))
    dataset = load_dataset(path)
    assert len(dataset) == 31 and dataset.samples[-1] == sample(99) and dataset.skipped == 1


def test_truncated_last_record_is_skipped_and_counted(tmp_path: Path) -> None:
    path = tmp_path / 'samples.jsonl'
    write(path, 4)
    data = path.read_bytes()
    path.write_bytes(data[:-25])   # the crash cut the last record short
    dataset = load_dataset(path)
    assert dataset.samples == [sample(i) for i in range(3)]
    assert dataset.skipped_lines == [5]
    with DatasetWriter(path) as writer:   # resuming never glues onto the partial line
        writer.append(sample(7))
    dataset = load_dataset(path)
    assert dataset.samples == [sample(0), sample(1), sample(2), sample(7)]
    assert dataset.skipped_lines == [5]


def test_corrupt_records_are_skipped_and_counted(tmp_path: Path) -> None:
    path = tmp_path / 'samples.jsonl'
    write(path, 5)
    lines = path.read_text().splitlines(keepends=True)
    lines[2] = lines[2].replace('"holes_used":7', '"holes_used":8')   # CRC mismatch
    lines[3] = 'not json at all\n'
    lines[4] = lines[4].replace('"sample":', '"sampel":')
    lines[5] = lines[5].replace('"holes_used":7', '"holes_used":1e999')   # int(inf): overflow
    path.write_text(''.join(lines))
    dataset = load_dataset(path)
    assert dataset.samples == [sample(0)]
    assert dataset.skipped_lines == [3, 4, 5, 6] and dataset.skipped == 4


def test_header_cut_at_creation(tmp_path: Path) -> None:
    path = tmp_path / 'samples.jsonl'
    path.write_bytes(b'{"format": "flexarm-defl')
    dataset = load_dataset(path)
    assert dataset.samples == [] and dataset.skipped == 1
    write(path, 2)
    assert load_dataset(path).samples == [sample(0), sample(1)]


def test_other_files_are_refused_and_left_alone(tmp_path: Path) -> None:
    path = tmp_path / 'notes.txt'
    path.write_text('shopping list')
    with pytest.raises(ValueError, match='not a flexarm-deflection-dataset'):
        DatasetWriter(path)
    with pytest.raises(ValueError, match='not a flexarm-deflection-dataset'):
        load_dataset(path)
    assert path.read_text() == 'shopping list'
    newer = tmp_path / 'newer.jsonl'
    newer.write_text('{"format": "flexarm-deflection-dataset", "version": 99}\n')
    with pytest.raises(ValueError, match='newer'):
        load_dataset(newer)


@pytest.mark.parametrize('header', [
    '{"format": "flexarm-deflection-dataset"}',
    '{"format": "flexarm-deflection-dataset", "version": "1"}',
    '{"format": "flexarm-deflection-dataset", "version": null}',
    '{"format": "flexarm-deflection-dataset", "version": true}',
    '["flexarm-deflection-dataset", 1]',
])
def test_damaged_header_is_refused_and_left_alone(tmp_path: Path, header: str) -> None:
    path = tmp_path / 'samples.jsonl'
    write(path, 2)
    content = header + '\n' + path.read_text().split('\n', 1)[1]
    path.write_text(content)
    with pytest.raises(ValueError, match='header|flexarm-deflection-dataset file'):
        load_dataset(path)
    with pytest.raises(ValueError, match='header|flexarm-deflection-dataset file'):
        DatasetWriter(path)
    assert path.read_text() == content


def test_bad_samples_are_rejected() -> None:
    good = sample(0)
    with pytest.raises(ValueError, match='joints needs 4'):
        Sample(**{**good.as_dict(), 'joints': [0.0, 0.6, 0.0]})
    with pytest.raises(ValueError, match='NaN'):
        Sample(**{**good.as_dict(), 'deflection': [0.0, math.nan, 0.0]})
    assert Sample.from_dict(good.as_dict()) == good


def test_a_sample_keeps_its_motion_and_a_record_without_one_still_loads(tmp_path):
    plain = Sample(1.0, [0.0, 0.6, 0.0, 0.0], 0.0, [1, 0, 0], [1, 0, 0], [0, 0, 0], 7, 1e-5)
    held = dataclasses.replace(plain, motion='3f0c')
    assert 'motion' not in plain.as_dict() and held.as_dict()['motion'] == '3f0c'
    path = tmp_path / 'd.jsonl'
    with DatasetWriter(path) as writer:
        writer.append(plain)
        writer.append(held)
    loaded = load_dataset(path)
    assert [s.motion for s in loaded.samples] == ['', '3f0c'] and loaded.skipped == 0
