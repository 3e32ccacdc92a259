"""The model directory record: damaged records are refused, versions never go back."""
import json

import pytest

from flexarm_deflection.model_store import (
    CURRENT,
    DamagedRecord,
    arm_fingerprint,
    damaged_text,
    find_model,
    fit_warning,
    list_models,
    next_version,
    payload_warning,
    provenance,
    read_current,
    unloadable_text,
    versions_on_disk,
    write_current,
)


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
    with pytest.raises(DamagedRecord, match=rf'{tmp_path / CURRENT} is damaged \(.+\); '
                       r'versions on disk: v7 \(`flexarm model use 7`'):
        read_current(tmp_path)
    assert next_version(tmp_path) == 8


def test_what_is_damaged_names_the_versions_still_on_disk(tmp_path):
    for name in ('a-gp-v10.model', 'b-rbf-v2.model', 'notes-v5.txt', 'x.model'):
        (tmp_path / name).write_bytes(b'')
    assert versions_on_disk(tmp_path) == [2, 10]
    assert damaged_text('f', 'why', []) == ('f is damaged (why); no model files on disk: '
                                            'collect and train')
    text = unloadable_text(tmp_path, {'version': '3', 'path': '/m/a-gp-v3.model'}, 'gone')
    assert text.startswith(f'{tmp_path / CURRENT}: its model v3 (/m/a-gp-v3.model) is damaged '
                           '(gone); versions on disk: v2, v10')


def test_record_ahead_of_the_files_wins(tmp_path):
    (tmp_path / 'good-rbf-v2.model').write_bytes(b'')
    (tmp_path / CURRENT).write_text(json.dumps({'version': '12', 'kind': 'rbf', 'path': 'x'}))
    assert next_version(tmp_path) == 13


def test_fit_warning_names_another_arm():
    arm = arm_fingerprint({'a': 1.0, 'b': [1, 2]})
    assert arm == arm_fingerprint({'b': [1, 2], 'a': 1.0}) != arm_fingerprint({'a': 1.5})
    meta = {'provenance': provenance('B', [0.0, 0.0, 5.0], arm)}
    assert meta['provenance']['payloads'] == [0.0, 5.0]
    assert fit_warning(meta, arm) == ''
    assert 'another arm configuration' in fit_warning(meta, arm_fingerprint({}))
    assert 'trained before' in fit_warning({}, arm)


def test_payload_warning_without_and_with_the_payload_input():
    assert payload_warning([0.0, 5.0], False, 5.0) == ''
    assert 'payload 0, 5 kg, the arm carries 2 kg' in payload_warning([0.0, 5.0], False, 2.0)
    assert payload_warning([0.0, 5.0], True, 2.5) == ''          # inside the trained range
    assert 'outside the payloads 0, 5 kg' in payload_warning([0.0, 5.0], True, 7.0)
    assert payload_warning([], False, 3.0) == ''                 # nothing known: no claim


def test_models_are_listed_by_version_and_found(tmp_path):
    for name in ('a-gp-v2.model', 'a-gp-v10.model', 'bad-rbf-v3.model', 'notes.model'):
        (tmp_path / name).write_text(name)
    write_current(tmp_path, 10, 'gp', str(tmp_path / 'a-gp-v10.model'), 'h')

    def read(path):
        if 'bad' in path.name:
            raise ValueError('damaged')
        return {'kind': path.name.split('-')[1]}

    entries = list_models(tmp_path, read)
    assert [(e.version, e.current) for e in entries] == [(2, False), (3, False), (10, True)]
    assert entries[1].metadata is None and entries[1].problem == 'damaged'
    assert find_model(tmp_path, '10').name == 'a-gp-v10.model'
    assert find_model(tmp_path, '2').name == 'a-gp-v2.model'      # not v12, not v20
    with pytest.raises(ValueError, match='no model version 4'):
        find_model(tmp_path, '4')
    with pytest.raises(ValueError, match='must be a number'):
        find_model(tmp_path, '1.model')
