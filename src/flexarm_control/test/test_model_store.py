"""The model directory record: damaged records are refused, versions never go back."""
import json

import pytest

from flexarm_control.model_store import (CURRENT, DamagedRecord, next_version, read_current,
                                         write_current)


def test_written_record_reads_back_and_versions_grow(tmp_path):
    assert read_current(tmp_path) is None and next_version(tmp_path) == 1
    write_current(tmp_path, 4, 'mlp', str(tmp_path / 'b-mlp-v4.model'), 'abc')
    assert read_current(tmp_path) == {'version': '4', 'kind': 'mlp',
                                      'path': str(tmp_path / 'b-mlp-v4.model'),
                                      'dataset_hash': 'abc'}
    assert next_version(tmp_path) == 5


@pytest.mark.parametrize('text', ['{"version": "2", "kind": "mlp"', '[1, 2]', '"v2"',
                                  '{"version": 2, "kind": "mlp", "path": "p"}',
                                  '{"version": "two", "kind": "mlp", "path": "p"}',
                                  '{"version": "2", "path": "p"}'])
def test_damaged_record_is_refused_and_model_files_keep_versions_growing(tmp_path, text):
    (tmp_path / CURRENT).write_text(text)
    (tmp_path / 'good-rbf-v7.model').write_bytes(b'')
    (tmp_path / 'notes-v99.txt').write_bytes(b'')
    with pytest.raises(DamagedRecord):
        read_current(tmp_path)
    assert next_version(tmp_path) == 8


def test_record_ahead_of_the_files_wins(tmp_path):
    (tmp_path / 'good-rbf-v2.model').write_bytes(b'')
    (tmp_path / CURRENT).write_text(json.dumps({'version': '12', 'kind': 'rbf', 'path': 'x'}))
    assert next_version(tmp_path) == 13
