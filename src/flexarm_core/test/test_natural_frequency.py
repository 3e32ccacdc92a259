"""The Table 6 tip frequency over payload and No.2 arm length, as the description holds it."""
import pytest

from flexarm_core.natural_frequency import NaturalFrequency
from flexarm_core.params import load_config

TABLE = load_config('arm.yaml')['arm']['tip_mode']['natural_frequency']


def test_natural_frequency_reproduces_table_6():
    table = NaturalFrequency.from_dict(TABLE)
    for payload, ext, hz in [(0.2, 0.16, 12.41), (0.2, 0.4, 11.85), (0.2, 0.8, 9.93),
                             (5.0, 0.16, 3.86), (5.0, 0.4, 3.77), (5.0, 0.8, 3.60)]:
        assert table(payload, ext) == pytest.approx(hz, rel=1e-9)
    assert table(5.0, 0.8) < table(2.0, 0.8) < table(0.2, 0.8) < table(0.0, 0.8)
    assert table(8.0, 0.8) == table(5.0, 0.8)          # held above the largest payload
    assert table(0.2, 0.1) == table(0.2, 0.16)         # clamped to the measured lengths


@pytest.mark.parametrize('change', [
    {'payloads': [5.0, 0.2], 'hz': [3.86, 3.77, 3.60, 12.41, 11.85, 9.93]},   # reversed
    {'extensions': [0.8, 0.4, 0.16]},
    {'extensions': [0.16, 0.16, 0.8]},
    {'payloads': [-0.2, 5.0]},
    {'extensions': [], 'hz': []},
])
def test_natural_frequency_table_must_be_ordered(change):
    with pytest.raises(ValueError, match='strictly increasing'):
        NaturalFrequency.from_dict({**TABLE, **change})


@pytest.mark.parametrize('change', [{'hz': [12.41, 11.85, 9.93, 3.86, 3.77]},
                                    {'hz': [12.41, 11.85, 9.93, 3.86, 3.77, 0.0]},
                                    {'payloads': [0.2], 'hz': [12.41, 11.85, 9.93]}])
def test_natural_frequency_table_must_be_complete_and_positive(change):
    with pytest.raises(ValueError, match='positive, payloads x extensions'):
        NaturalFrequency.from_dict({**TABLE, **change})
