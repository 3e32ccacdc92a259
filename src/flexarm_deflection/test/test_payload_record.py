"""The declared payload survives a restart: stored atomically, a damaged record said."""
import pytest

from flexarm_deflection.payload_record import payload_path, read_payload, write_payload


def test_a_declaration_reads_back_and_none_is_none(tmp_path):
    assert read_payload(tmp_path / 'models') is None
    write_payload(tmp_path / 'models', 5.0)
    assert read_payload(tmp_path / 'models') == 5.0
    write_payload(tmp_path / 'models', 0.0)
    assert read_payload(tmp_path / 'models') == 0.0
    assert [p.name for p in (tmp_path / 'models').iterdir()] == ['payload.json']   # no temp


@pytest.mark.parametrize('text, reason', [
    ('{"payload": -1}', 'not a finite number'), ('{"payload": "5"}', 'not a finite number'),
    ('{"payload": true}', 'not a finite number'), ('{"kg": 5}', 'KeyError'),
    ('{"payload": 5', 'JSONDecodeError'), ('[5]', 'TypeError'), ('{"payload": NaN}', 'finite')])
def test_a_damaged_record_names_its_file_and_why(tmp_path, text, reason):
    payload_path(tmp_path).write_text(text)
    with pytest.raises(ValueError) as error:
        read_payload(tmp_path)
    assert str(payload_path(tmp_path)) in str(error.value) and reason in str(error.value)
