"""Smoke runs of the endurance harnesses of this folder (soak, faults, lifecycle: pass/fail runs
of hours of operation), each at its smallest size and with the benchmarks' checks
(:mod:`flexarm_test_support.script_smoke`: it exits 0, its JSON line holds the keys a reader
relies on); a harness rots where nothing runs it.
The endurance tier: ``pytest -m endurance`` runs it, the default run leaves it out (pytest.ini).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from flexarm_test_support.script_smoke import Smoke, run, scheduled

REPO = Path(__file__).resolve().parents[2]
FOLDER = 'tests/endurance'
pytestmark = pytest.mark.endurance


def _faults_ran(figures: dict[str, Any]) -> None:
    """The scenario ran: faults.py reports a scenario's or graph's failure as a row."""
    rows = figures['scenarios']
    assert [row['scenario'] for row in rows] == ['SIGTERM of flexarm up (idle)'], rows
    assert not [row for row in rows if 'error:' in row['note']], rows


def _graph_stop_judged(figures: dict[str, Any]) -> None:
    """The cycle's node and then every node of the graph at its stop were judged."""
    assert figures['graph_stops'] == 1, figures
    stops = {name: node['stops'] for name, node in figures['per_node'].items()}
    assert stops.pop('flexarm_state_publisher') == 2 and len(stops) >= 6, stops
    assert set(stops.values()) == {1}, stops


HARNESSES = [
    Smoke('faults', ('--only', 'sigterm_idle'), ('lost_samples', 'orphans', 'scenarios'),
          ('max_detect_s',), timeout=120.0, check=_faults_ran, seconds=14),
    Smoke('lifecycle', ('--cycles', '1', '--nodes', 'state_publisher'),
          ('crashes', 'hung', 'signal_exits', 'stops', 'graph_stops', 'per_node'),
          ('crashes', 'stops', 'graph_stops'), check=_graph_stop_judged,
          timeout=150.0, domain='--domain-id', seconds=30),
    Smoke('soak', ('--smoke',),
          ('goals', 'succeeded', 'unfinished_goals', 'false_success', 'concurrent_motion',
           'crashes', 'rss_growth_mb', 'fd_growth', 'lost_samples', 'arm_hours', 'wall_s',
           'restarts', 'refused_busy', 'achieved_rtf'),
          ('goals.total', 'unfinished_goals', 'false_success', 'concurrent_motion', 'crashes',
           'lost_samples', 'arm_hours', 'achieved_rtf'),
          timeout=360.0, domain='--domain-id', seconds=105),
]


def test_every_harness_has_a_smoke_run() -> None:
    present = {path.stem for path in (REPO / FOLDER).glob('*.py')} - {Path(__file__).stem}
    assert present == {smoke.name for smoke in HARNESSES}


@pytest.mark.node
@pytest.mark.parametrize('smoke', [scheduled(smoke) for smoke in HARNESSES], ids=str)
def test_harness_runs(smoke: Smoke, domain_id: int) -> None:
    run(smoke, domain_id, FOLDER)
