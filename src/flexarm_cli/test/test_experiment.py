"""``flexarm demo``'s account of its time: the phases (pure), and the demo itself, recorded,
ending its ``--json`` output with ``seconds`` and ``achieved_rtf`` (a node test)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from flexarm_cli.experiment import Phases, phases_text
from flexarm_core import liveness
from flexarm_recording.bag_tools import bag_info

DEMO_S = 140.0   # [s, liveness-scaled] a bound for a demo that hangs; it takes about 30 s


class FakeSim:
    """Simulated time on demand: ``at`` [s], None for a graph without /clock."""

    def __init__(self) -> None:
        self.at: float | None = 0.0

    def now(self, timeout: float = 5.0) -> float | None:
        return self.at


def test_phases_give_wall_and_simulated_seconds_and_the_achieved_factor() -> None:
    wall, sim = [100.0], FakeSim()
    sim.at = 12.0
    phases = Phases(sim, started=96.0, clock=lambda: wall[0])
    wall[0], sim.at = 110.0, 112.0
    phases.mark('collect A', samples=40)
    wall[0], sim.at = 115.0, 137.0
    phases.mark('train A')
    rtf = phases.achieved_rtf()
    assert rtf == pytest.approx(125.0 / 15.0)
    wall[0] = 116.0
    phases.mark('shutdown', graph=False)
    start, collect, train, shutdown = phases.rows
    assert start == {'phase': 'start', 'seconds': 4.0}
    assert collect == {'phase': 'collect A', 'seconds': 10.0, 'samples': 40,
                       'sim_seconds': 100.0, 'rtf': 10.0}
    assert (train['sim_seconds'], train['rtf']) == (25.0, 5.0)
    assert shutdown == {'phase': 'shutdown', 'seconds': 1.0}
    text = phases_text({'phases': phases.rows, 'achieved_rtf': rtf})
    assert 'collect A 10.0 s (40 samples, x10.0)' in text and 'shutdown 1.0 s' in text
    assert text.endswith('x8.33 real time achieved from ready to the last goal')


def test_a_graph_without_clock_has_no_factor() -> None:
    sim = FakeSim()
    sim.at = None
    phases = Phases(sim, started=0.0, clock=lambda: 1.0)
    phases.mark('goals A', goals=9)
    assert phases.achieved_rtf() is None
    assert 'rtf' not in phases.rows[-1]
    assert 'achieved' not in phases_text({'phases': phases.rows, 'achieved_rtf': None})


@pytest.mark.node
@pytest.mark.duration(100)
@pytest.mark.timeout(liveness.limit(DEMO_S + 30.0))
def test_recorded_demo_json_ends_with_its_time_and_real_time_factor(
        domain_id: int, tmp_path: Path) -> None:
    """The smallest demo (ideal world, 8 samples a region, the grey-box model), with its
    bag: the JSON line has ``seconds``, ``achieved_rtf`` and the phases, the bag decodes."""
    done = subprocess.run(
        [sys.executable, '-m', 'flexarm_cli', 'demo', '--json', '--ideal',
         '--samples', '8', '--kind', 'greybox', '--name', 'timed',
         '--domain-id', str(domain_id)],
        capture_output=True, text=True, timeout=liveness.limit(DEMO_S),
        stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    out: dict[str, Any] = json.loads(done.stdout.splitlines()[-1])
    assert out['ok'] and out['exit_code'] == 0
    assert out['seconds'] > 0
    assert 1.0 < out['achieved_rtf'] < 10.5          # the simulator runs at x10 at most
    assert [p['phase'] for p in out['phases']] == [
        'start', 'collect A', 'train A', 'load model A', 'goals A', 'collect B', 'train B',
        'load model B', 'goals B', 'shutdown', 'results']
    assert sum(p['seconds'] for p in out['phases']) == pytest.approx(out['seconds'], abs=0.5)
    assert 'real time achieved' in done.stdout
    info = bag_info(out['bag'])
    assert info['complete'] and info['rosbag2_metadata']
    factory, decoded = DecoderFactory(), 0
    with open(info['path'], 'rb') as f:
        for schema, channel, message in make_reader(f).iter_messages():
            factory.decoder_for(channel.message_encoding, schema)(message.data)
            decoded += 1
    assert decoded == info['message_count'] > 1000
    assert info['topics']['/compensator/outcomes']['count'] == 18
