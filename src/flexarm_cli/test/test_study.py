"""The sensitivity study: its grid, its settings, and a tiny run that writes its files."""
import csv
import json
import math

import pytest

from flexarm_cli.study import (
    PAPER_HIDDEN,
    configurations,
    main,
    run_study,
    study_settings,
    write_study,
)
from flexarm_core.paper import TABLE_7, TABLE_8

pytestmark = pytest.mark.duration(25)


def test_grid_holds_the_paper_tables_then_the_extended_grid_without_repeats():
    configs = configurations(study_settings({'samples': [40, 20]}))
    assert configs[:len(TABLE_7)] == [('mlp', h, 50) for h in TABLE_7]
    assert {('mlp', PAPER_HIDDEN, n) for n in TABLE_8} <= set(configs)
    assert {('rbf', None, 20), ('gp', None, 40), ('mlp', PAPER_HIDDEN, 20)} <= set(configs)
    assert len(configs) == len(set(configs))
    assert configurations(study_settings({'samples': [20], 'kinds': ['rbf'],
                                          'paper_tables': False})) == [('rbf', None, 20)]


def test_predictor_settings_merge_per_kind_and_bad_ones_are_refused():
    s = study_settings({'predictors': {'mlp': {'members': 2}}})
    assert s['predictors']['mlp']['members'] == 2
    assert s['predictors']['mlp']['max_iterations'] == 1000   # the study's own, kept
    for bad in ({'colour': 1}, {'predictors': {'mlp': {'units': 3}}}, {'kinds': ['svm']},
                {'seeds': 0}):
        with pytest.raises(ValueError):
            study_settings(bad)


def test_tiny_study_writes_its_files_and_learns_the_deflection(tmp_path):
    steps = []
    result = run_study({'seeds': 1, 'samples': [20], 'held_out': 50, 'kinds': ['mlp', 'rbf'],
                        'paper_tables': False}, progress=lambda *step: steps.append(step))
    assert steps == [(0, 3, 'learning data, seed 0'), (1, 3, 'mlp 10 hidden, 20 samples'),
                     (2, 3, 'rbf, 20 samples'), (3, 3, 'done')]
    rows = result['rows']
    assert [(r['kind'], r['samples']) for r in rows] == [('mlp', 20), ('rbf', 20)]
    # The arm sags ~20 mm in this workspace; a learned predictor must do far better than that.
    assert result['largest_deflection_mm'] > 10
    for r in rows:
        errors = [r['max_x_mm'], r['max_y_mm'], r['worst_position_mm']]
        assert all(math.isfinite(e) and 0 < e < 0.2 * result['largest_deflection_mm']
                   for e in errors)
        assert 0 < r['max_phi_deg'] < 0.2 and 0 < r['normalised'] < 0.2
    paths = write_study(result, tmp_path)
    table = paths['table'].read_text()
    assert 'Table 7' in table and 'Table 8' in table and '| 20 |' in table
    assert str(TABLE_8[40][0]) in table    # the paper's figures next to ours
    with open(paths['csv']) as f:
        written = list(csv.DictReader(f))
    assert [(w['kind'], int(w['samples'])) for w in written] == [('mlp', 20), ('rbf', 20)]
    assert paths['plot'].read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        'learning_curve.png', 'study.csv', 'table.md']     # no temporary file left


def test_main_refuses_an_unknown_region_and_prints_json_last(tmp_path, capsys):
    assert main(['--region', 'nowhere', '--out', str(tmp_path)]) == 2
    assert 'unknown region' in capsys.readouterr().err
    assert main(['--quick', '--seeds', '1', '--out', str(tmp_path), '--json', '--predictors',
                 '{"mlp": {"max_iterations": 100}}']) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert last['ok'] and last['settings']['predictors']['mlp']['max_iterations'] == 100
    assert (tmp_path / 'paper' / 'table.md').exists()
