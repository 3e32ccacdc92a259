"""The sensitivity study on a tiny grid: files written, errors sane."""
import csv

from flexarm_control.study import run_study, write_study


def test_quick_study_writes_its_tables_and_learns(tmp_path):
    rows = run_study('paper', seeds=1, samples=(20,), held_out=30)
    kinds = {(r.kind, r.samples) for r in rows}
    assert {('mlp', 50), ('mlp', 30), ('mlp', 40), ('rbf', 20), ('gp', 20)} <= kinds
    for r in rows:
        # The arm sags ~10-20 mm here; a learned predictor must do far better than that.
        assert 0 < r.max_y_mm < 3.0 and 0 < r.max_phi_deg < 0.2 and 0 < r.normalised < 0.2
    paths = write_study(rows, tmp_path)
    assert 'Table 8' in paths['table'].read_text()
    with open(paths['csv']) as f:
        assert len(list(csv.DictReader(f))) == len(rows)
    assert paths['plot'].stat().st_size > 10_000
