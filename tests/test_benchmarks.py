"""Smoke runs of every benchmark in benchmarks/: benchmarks rot where nothing runs them.

Each test runs one benchmark as a script at its smallest size (a few seconds; a cheap predictor
kind where training would dominate) and checks that it exits 0 and that its JSON line (the last
of stdout) holds the keys a reader relies on, their numbers finite where they are even at that
size. The figures themselves stay the benchmarks' job: nothing here judges a value. The
endurance harnesses (pass/fail runs of hours of operation) live in tests/endurance/, their smoke
runs (with this module's checks) in its test_endurance.py.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from flexarm_test_support.script_smoke import Smoke, run, scheduled

REPO = Path(__file__).resolve().parents[1]


# Offline: the control core on the static simulated arm, no ROS node.
OFFLINE = [
    Smoke('plant', (), ('pose_us', 'batch_10000_ms', 'table10'),
          ('pose_us', 'batch_10000_ms')),
    Smoke('camera_robustness', ('--poses', '2', '--scales', '1'),
          ('poses', 'cases', 'worst', 'worst_10x'), ('worst.valid_fraction',)),
    Smoke('vision', ('--count', '10'), ('valid_rate', 'position_error_mean_mm',
                                        'frames_per_second'),
          ('valid_rate', 'position_error_mean_mm', 'frames_per_second')),
    Smoke('robustness', ('--seeds', '1', '--targets', '2', '--samples', '12', '--regions', 'A',
                         '--kind', 'kinematic'),
          ('refused', 'max_mm', 'p95_mm', 'outlier'), ('max_mm', 'max_deg')),
    Smoke('error_budget', ('--seeds', '1', '--targets', '2', '--samples', '12', '--regions', 'A',
                           '--kind', 'kinematic', '--workers', '1'),
          ('sources', 'all', 'all_uncalibrated'),
          ('all.closed_loop_p95_mm', 'all.predictive_p95_mm', 'sources.camera.after_mm'),
          seconds=9),
    Smoke('drift', ('--seeds', '1', '--targets', '2', '--samples', '12', '--regions', 'A',
                    '--kind', 'kinematic', '--workers', '1'),
          ('scenarios',),
          ('scenarios.payload.refreshed_p95_mm', 'scenarios.none.refreshed_p95_mm'), seconds=9),
    Smoke('payload', ('--seeds', '1', '--samples', '12', '--held-out', '2', '--regions', 'A',
                      '--kind', 'kinematic', '--workers', '1'),
          ('regions', 'ratio'), ('ratio',)),
    Smoke('shaping', ('--moves', '1', '--campaign', '0'),
          ('shapers', 'residual_mm_p95', 'settle_s_p95', 'frequency_error_residual_mm_p95'),
          ('residual_mm_p95', 'settle_s_p95', 'settle_s_p95_off'), seconds=6),
    Smoke('training', ('--samples', '12', '--repeats', '1', '--kinds', 'kinematic,gp'),
          ('samples', 'kinematic', 'gp'), ('kinematic.fit_s', 'gp.fit_s')),
    Smoke('uncertainty', ('--smoke',),
          ('coverage', 'coverage_min', 'sharpness', 'unsafe_moves', 'mlp_fit_s', 'scenarios'),
          ('coverage', 'sharpness', 'mlp_fit_s', 'scenarios.nominal.median_bound_mm'),
          seconds=30),
    Smoke('compensation', ('--kind', 'kinematic', '--targets', 'A1', '--samples', '12'),
          ('kind', 'rows', 'predictive_max_ms'), ('predictive_max_ms',)),
    # the learning core on the shared UR10 laser-tracker measurements (its smallest series, and
    # series A through the night)
    Smoke('core_on_jaeri', ('--regions', 'A', '--samples', '12', '--held-out', '5'),
          ('samples', 'held_out', 'regions'),
          ('regions.A.greybox_mean_mm', 'regions.A.structure_mean_mm', 'regions.A.predict_ms')),
    Smoke('real_arm', ('--series', 'D', '--others', 'A', '--sizes', '20', '--splits', '1'),
          ('series', 'mean_mm_20', 'coverage_20', 'ratio_20', 'reference_mean_mm_20',
           'coverage_overnight', 'coverage_overnight_fixed'),
          ('mean_mm_20', 'fit_s_20', 'coverage_overnight', 'sharpness_overnight'), seconds=20),
    # The README's headline figures as last measured, checked (measuring them takes minutes)
    Smoke('headline', ('--only', '', '--no-write'), ('figures', 'no_longer_hold')),
    # The README's test command on a module of this checkout (a fresh clone sets up a venv).
    Smoke('suite', ('--here', '--runs', '1', '--tests',
                    '-n 0 src/flexarm_control/test/test_modes.py'),
          ('runs', 'failures', 'median_s'), ('failures', 'median_s')),
]

# Start ROS nodes: in the test module's domain where the benchmark takes one, else in a free
# one the benchmark reserves itself (flexarm_cli.experiment.reserved_domain).
NODE = [
    Smoke('bridge', ('--moves', '1', '--robot-only'), ('sim', 'bridge', 'added_median_ms'),
          ('added_median_ms',), domain='--domain', seconds=10),
    Smoke('bringup', ('--runs', '1', '--status-calls', '1'), ('ready_s', 'status_s', 'stop_s'),
          ('ready_s', 'status_s', 'stop_s'), seconds=25),
    # one graph of the three (each measures the same way): the one with the most in it
    Smoke('footprint', ('--smoke', '--graphs', 'x10_recorded'),
          ('idle_x10_recorded', 'collect_x10_recorded', 'rss_mb_total', 'nodes', 'recorder'),
          ('idle_x10_recorded.total_cores', 'collect_x10_recorded.achieved_rtf',
           'collect_x10_recorded.s_per_sample_wall', 'rss_mb_total',
           'recorder.cores.collect_x10'),
          timeout=150.0, domain='--domain-id', seconds=25),
    Smoke('multi_arm', ('--arms', '1', '--goals', '1', '--kind', 'kinematic'),
          ('goals_per_min', 'crosstalk', 'cpu'), ('goals_per_min.1.total',), timeout=120.0,
          seconds=30),
    Smoke('recorder', ('--seconds', '1'), ('messages_per_s', 'dropped', 'clean_close'),
          ('messages_per_s', 'image_mb_per_s'), domain='--domain-id', seconds=10),
    # the offline learning curves, then the campaigns through a running graph
    Smoke('sample_efficiency', ('--seeds', '1', '--regions', 'A', '--counts', '12',
                                '--held-out', '2', '--kinds', 'kinematic', '--campaign', '2',
                                '--workers', '1'),
          ('samples_for_1mm', 'curves', 'campaign_s_per_sample'),
          ('curves.sobol.A.0.worst_max_mm', 'campaign_s_per_sample.sobol',
           'campaign_s_per_sample.active'), timeout=150.0, seconds=45),
    Smoke('sim_node', ('--seconds', '1'), ('runs',),
          ('runs.0.rate_wall_hz', 'runs.1.rate_wall_hz'), domain='--domain-id', seconds=13),
]
# Benchmarks whose smoke runs their owners are adding
PENDING: set[str] = set()


def test_the_suite_runs_without_a_venvs_libraries(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """benchmarks/suite.py's clone gets no LD_LIBRARY_PATH entry of a venv (this checkout's,
    inherited from its bootstrap): its processes would load those message libraries or the
    clone's own, each at random, and disagree on a message's layout."""
    spec = importlib.util.spec_from_file_location('benchmark_suite', REPO / 'benchmarks/suite.py')
    suite = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(suite)
    venv = tmp_path / '.venv'
    (venv / 'lib' / 'python3.11' / 'site-packages' / 'ros_rclpy.libs').mkdir(parents=True)
    (venv / 'pyvenv.cfg').write_text('home = /usr/bin\n')
    ours = [str(venv / 'lib' / 'python3.11' / 'site-packages' / 'ros_rclpy.libs'),
            str(venv / 'lib')]
    monkeypatch.setenv('_ROS_WHEELS_BOOTSTRAP_COMPLETE', '1')
    monkeypatch.setenv('LD_LIBRARY_PATH', ':'.join([ours[0], '/opt/vendor/lib', ours[1]]))
    env = suite.clean_env()
    assert env['LD_LIBRARY_PATH'] == '/opt/vendor/lib'
    assert '_ROS_WHEELS_BOOTSTRAP_COMPLETE' not in env
    monkeypatch.setenv('LD_LIBRARY_PATH', ':'.join(ours))
    assert 'LD_LIBRARY_PATH' not in suite.clean_env()


def test_every_benchmark_has_a_smoke_run() -> None:
    present = {path.stem for path in (REPO / 'benchmarks').glob('*.py')}
    covered = {smoke.name for smoke in OFFLINE + NODE}
    assert not present - covered - PENDING, f'no smoke run: {sorted(present - covered - PENDING)}'
    assert not covered - present, f'smoke runs of no benchmark: {sorted(covered - present)}'


@pytest.mark.benchmark
@pytest.mark.parametrize('smoke', [scheduled(smoke) for smoke in OFFLINE], ids=str)
def test_offline_benchmark_runs(smoke: Smoke) -> None:
    run(smoke)


@pytest.mark.benchmark
@pytest.mark.node
@pytest.mark.parametrize('smoke', [scheduled(smoke) for smoke in NODE], ids=str)
def test_node_benchmark_runs(smoke: Smoke, domain_id: int) -> None:
    run(smoke, domain_id)
