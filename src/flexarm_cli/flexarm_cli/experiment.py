"""``flexarm demo`` / ``flexarm benchmark``: the paper's experiment on the simulated arm.

Brings the graph up in a private ROS domain (one run folder with every node's log, one bag),
then per working region: collects learning samples (dataset = the region's name), trains the
predictor, waits until the compensator has hot-reloaded it, and runs that region's targets in
RIGID, PREDICTIVE and CLOSED_LOOP modes, judged against the simulator's ground truth.

Where the time goes: the summary's ``phases`` list each phase (start, calibration, and per
region collect, train, load model, goals; then shutdown and results) with its wall seconds
and, while the graph runs, the simulated seconds it advanced and their ratio (``rtf``), from
the newest ``/clock`` taken without waking the client (:class:`SimTime`). ``seconds`` is the
wall time of the whole run (graph start to results written), ``achieved_rtf`` the simulated
time advanced per wall second from the graph ready to the end of the last goal.

Decision: one predictor per working region, as the paper's benchmark uses two separate
working spaces (A, B) — 40 samples over both at once fit 4-7x worse (offline on the plant:
max error 1.7 mm over A+B against 0.26 mm in A alone and 0.45 mm in B alone). The
compensator holds one model at a time, so the regions run in turn.
"""
from __future__ import annotations

import contextlib
import json
import math
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from flexarm_bringup.domains import reserved
from flexarm_bringup.launcher import node_name
from flexarm_bringup.supervisor import Graph
from flexarm_cli.calibration import calibrate_tool
from flexarm_control.execution.modes import MODE_LABELS
from flexarm_core import topics
from flexarm_core.kinematics import ArmGeometry, pose_error
from flexarm_core.paper import TABLE_9, TABLE_10
from flexarm_core.params import load_config
from flexarm_core.paths import BAGS_DIR, RESULTS_DIR, RUNS_DIR
from flexarm_core.regions import Region, configured_regions
from flexarm_deflection.dataset import load_dataset
from flexarm_deflection.sampling import random_targets
from flexarm_recording.bag_tools import ACCURACY_CODES
from flexarm_recording.results.trials import (
    MOVE_CSV_FIELDS,
    TRIAL_CSV_FIELDS,
    Trial,
    TruthMonitor,
    run_trials,
    summarise,
)

if TYPE_CHECKING:
    from flexarm_control.ros.client import FlexarmClient


@dataclass
class ExperimentSettings:
    name: str
    samples: int = 40                 # learning samples per region
    kind: str = ''                    # predictor kind ('': the learner's default)
    random_targets: int = 0           # held-out random targets per region (A and B)
    table9: bool = False              # also the Table 9 targets (region 'paper')
    real_time_factor: float = 10.0
    record: bool = True               # write bags/<name>/<name>.mcap
    seed: int = 1
    modes: tuple[str, ...] = MODE_LABELS[:3]   # the paper's comparison: no AUTO
    ready_timeout: float = 120.0
    extra_parameters: dict = field(default_factory=dict)
    world: dict = field(default_factory=dict)   # simulator parameters, e.g. the ideal world


@contextlib.contextmanager
def reserved_domain(domain_id: int | None) -> Iterator[int]:
    """The given ROS domain, or a free one reserved for this process."""
    with reserved(domain_id) as did:
        yield did


def _targets(settings: ExperimentSettings, region: str, geometry: ArmGeometry,
             regions: dict) -> list[tuple[str, str, str, np.ndarray]]:
    chosen = [(t.name, 'table10', region, t.pose) for t in TABLE_10 if t.region == region]
    if region == 'paper':
        chosen += [(name, 'table9', region, np.array([x / 1e3, y / 1e3, math.radians(phi)]))
                   for name, (x, y, phi), _, _ in TABLE_9]
    elif settings.random_targets:
        poses = random_targets(geometry, regions[region], settings.random_targets,
                               seed=10_000 + settings.seed)
        chosen += [(f'{region}r{i:03d}', 'random', region, p) for i, p in enumerate(poses)]
    return chosen


def run_experiment(settings: ExperimentSettings, domain_id: int,
                   say: Callable[[str], None] = print, progress: bool = True) -> dict:
    """Run it; returns the summary and writes results/<name>/ (JSON, CSV, PNG)."""
    run_dir = RUNS_DIR / settings.name
    out_dir = RESULTS_DIR / settings.name
    geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
    regions = configured_regions(node_name('learner'))
    optional = (node_name('recorder'),) if settings.record else ()
    region_names = ['A', 'B'] + (['paper'] if settings.table9 else [])
    trials: list[Trial] = []
    learning: dict[str, dict] = {}
    started = time.monotonic()
    graph = Graph(domain_id, run_dir, parameters=_run_parameters(settings, run_dir),
                  optional=optional, report=say)
    say(f'starting the graph in ROS domain {domain_id}; logs in {run_dir}')
    watchdog = _Watchdog(graph)
    with graph, graph_client(domain_id) as client, contextlib.closing(watchdog):
        graph.wait_ready(settings.ready_timeout)
        watchdog.start()
        say(f'graph ready after {time.monotonic() - started:.1f} s')
        client.wait_until_ready(timeout=30.0)
        phases = Phases(SimTime(client), started)
        truth = TruthMonitor(client)
        calibration = None
        if not settings.world:          # the realistic world: calibrate the camera first
            calibration = _calibrate(client, run_dir, say)
            phases.mark('calibration')
        for region in region_names:
            learning[region] = _learn(client, settings, region, run_dir, phases, say, progress)
            targets = _targets(settings, region, geometry, regions)
            trials += _goals(client, truth, targets, settings, region, progress)
            phases.mark(f'goals {region}', goals=len(targets) * len(settings.modes))
        achieved_rtf = phases.achieved_rtf()
    phases.mark('shutdown', graph=False)
    summary = {'name': settings.name, 'seconds': time.monotonic() - started,
               'achieved_rtf': achieved_rtf, 'phases': phases.rows,
               'world': 'ideal' if settings.world else 'realistic',
               'tool_calibration': calibration,
               'learning': learning, 'summary': summarise(trials),
               'trials': [t.as_dict() for t in trials],
               'bag': str(BAGS_DIR / settings.name) if settings.record else None,
               'nodes_died': watchdog.dead}
    write_results(summary, trials, out_dir, geometry, regions)
    phases.mark('results', graph=False)
    summary['seconds'] = time.monotonic() - started
    write_summary(summary, out_dir)             # with the whole run's time
    summary['results'] = str(out_dir)
    return summary


def _run_parameters(settings: ExperimentSettings, run_dir: Path) -> dict[str, dict]:
    """The run's parameters over graph.yaml's: its simulator settings, and its own data,
    models, bag and calibrations in the run folder (never the site's calibration/ files)."""
    return {
        node_name('simulator'): {'real_time_factor': settings.real_time_factor,
                                 **settings.world},
        node_name('learner'): {'data_directory': str(run_dir / 'data'),
                               'model_directory': str(run_dir / 'models')},
        node_name('recorder'): {'bag_name': settings.name},
        node_name('vision'): {'tool_calibration_file': str(run_dir / 'tool_camera.json'),
                              'camera_calibration_file': str(run_dir / 'camera.json')},
        **settings.extra_parameters}


def _calibrate(client: FlexarmClient, run_dir: Path, say: Callable[[str], None]) -> dict:
    """The tool calibration against the reference (the ground truth), as the summary has it."""
    correction, found, _ = calibrate_tool(client, topics.TIP_POSE_TRUTH,
                                          run_dir / 'tool_camera.json', say=say)
    calibration = {'axial_mm': correction.axial * 1e3,
                   'lateral_mm': correction.lateral * 1e3,
                   'angle_deg': math.degrees(correction.angle), 'poses': found.poses,
                   'spread_mm': found.spread[0] * 1e3}
    say(f'tool calibration against the reference (the ground truth): camera error '
        f'axial {calibration["axial_mm"]:.4f} mm, lateral '
        f'{calibration["lateral_mm"]:.4f} mm, {calibration["angle_deg"]:.5f} deg')
    return calibration


def _learn(client: FlexarmClient, settings: ExperimentSettings, region: str, run_dir: Path,
           phases: Phases, say: Callable[[str], None], progress: bool) -> dict:
    """Collect the region's samples, train on them and wait for the model: what it learned."""
    from tqdm import tqdm

    bar = tqdm(total=settings.samples, desc=f'collect {region}', unit='sample',
               disable=not progress)
    collected = client.collect(
        settings.samples, region=region, dataset=region, seed=settings.seed,
        feedback=lambda fb: (bar.update(fb.k - bar.n), bar.set_postfix(skipped=fb.skipped)))
    bar.close()
    if collected.error_code != 0:
        raise RuntimeError(f'collection in {region} failed: {collected.error_string}')
    phases.mark(f'collect {region}', samples=collected.collected)
    trained = client.train(settings.kind, dataset=region)
    if not trained.success:
        raise RuntimeError(f'training on {region} failed: {trained.message}')
    phases.mark(f'train {region}')
    model = client.wait_for_model(trained.model_version)
    phases.mark(f'load model {region}')
    m = trained.metrics
    say(f'region {region}: {collected.total} samples, model v{trained.model_version} '
        f'{m.selected_settings}: {m.validation} max |error| {m.max_error_x * 1e3:.3f} '
        f'mm (x), {m.max_error_y * 1e3:.3f} mm (y), '
        f'{math.degrees(m.max_error_phi):.4f} deg; '
        f'{len(m.excluded_samples)} sample(s) excluded as outliers')
    return {'samples': collected.total, 'skipped': collected.skipped,
            'model_version': trained.model_version, 'model_path': model.path,
            'dataset_path': str(run_dir / 'data' / f'{region}.jsonl'),
            'validation': m.validation,
            'max_error_x_mm': m.max_error_x * 1e3, 'max_error_y_mm': m.max_error_y * 1e3,
            'max_error_phi_deg': math.degrees(m.max_error_phi),
            'selected_settings': m.selected_settings,
            'excluded_samples': list(m.excluded_samples)}


def _goals(client: FlexarmClient, truth: TruthMonitor, targets: list,
           settings: ExperimentSettings, region: str, progress: bool) -> list[Trial]:
    """Every target of the region in every mode of the run, with a progress bar."""
    from tqdm import tqdm

    bar = tqdm(total=len(targets) * len(settings.modes), desc=f'targets {region}',
               unit='goal', disable=not progress)
    trials = run_trials(client, truth, targets, settings.modes, settings.name,
                        on_trial=lambda t: bar.update(1))
    bar.close()
    return trials


class SimTime:
    """The graph's simulated time [s], the newest ``/clock`` taken from a raw keep-last-1
    subscription that never wakes the client (:class:`flexarm_core.ros.taken.Taken`)."""

    def __init__(self, node: Any) -> None:
        from rclpy.qos import QoSProfile
        from rosgraph_msgs.msg import Clock

        from flexarm_core.ros.taken import Taken

        self._subscription = node.create_subscription(
            Clock, topics.CLOCK, lambda _: None, QoSProfile(depth=1), callback_group=Taken(),
            raw=True)
        self._ns: int | None = None

    def now(self, timeout: float = 5.0) -> float | None:
        """The newest ``/clock`` [s]; waits up to ``timeout`` for the first one (None if none
        came: a graph on wall time)."""
        from flexarm_core.ros.stamps import raw_stamp_ns
        from flexarm_core.ros.taken import take

        deadline = time.monotonic() + timeout
        while True:
            while (raw := take(self._subscription)) is not None:
                self._ns = raw_stamp_ns(raw)
            if self._ns is not None or time.monotonic() > deadline:
                return None if self._ns is None else self._ns * 1e-9
            time.sleep(0.01)


MIN_PHASE = 0.5     # [s, wall] the shortest phase given its real-time factor (/clock: 25 Hz)


class Phases:
    """Where a run's time goes: per phase its wall seconds and the simulated seconds the graph
    advanced meanwhile (``rtf``: their ratio, for a phase of ``MIN_PHASE`` or more), from
    :class:`SimTime` marks."""

    def __init__(self, sim: SimTime, started: float,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """``started``: when the run began (``clock``'s time); the first phase, ``start``,
        ends now (the graph is ready)."""
        self._sim, self._clock = sim, clock
        self._start = self._last = (clock(), sim.now())
        self.rows: list[dict[str, Any]] = [
            {'phase': 'start', 'seconds': self._start[0] - started}]

    def mark(self, phase: str, graph: bool = True, **extra: Any) -> None:
        """The phase that ends now (``graph``: the graph still runs, its time is read)."""
        now = (self._clock(), self._sim.now(timeout=0.0) if graph else None)
        row: dict[str, Any] = {'phase': phase, 'seconds': now[0] - self._last[0], **extra}
        if now[1] is not None and self._last[1] is not None:
            row['sim_seconds'] = now[1] - self._last[1]
            if row['seconds'] >= MIN_PHASE:         # else a /clock period or two: no ratio
                row['rtf'] = row['sim_seconds'] / row['seconds']
        self.rows.append(row)
        self._last = now if now[1] is not None else (now[0], self._last[1])

    def achieved_rtf(self) -> float | None:
        """Simulated seconds per wall second from the first mark (the graph ready) to now."""
        wall, sim = self._clock(), self._sim.now(timeout=0.0)
        if sim is None or self._start[1] is None:
            return None
        return (sim - self._start[1]) / max(wall - self._start[0], 1e-9)


class _Watchdog:
    """Checks the graph's processes once a second while the experiment runs."""

    def __init__(self, graph: Graph) -> None:
        self.dead: list[str] = []
        self._stop = threading.Event()
        self._graph = graph
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.wait(1.0):
            self.dead += self._graph.check()

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)


@contextlib.contextmanager
def graph_client(domain_id: int):
    import rclpy
    from rclpy.context import Context

    from flexarm_control.ros.client import FlexarmClient

    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    client = FlexarmClient('flexarm_experiment', context=context,
                           learner_node=node_name('learner'))
    try:
        yield client
    finally:
        client.destroy_node()
        rclpy.try_shutdown(context=context)


def phases_text(summary: dict) -> str:
    """Where the run's wall time went, phase by phase (with the real-time factor the graph
    achieved in each), and the achieved factor over the run."""
    parts = []
    for row in summary['phases']:
        notes = [f'{row[key]} {key}' for key in ('samples', 'goals') if key in row]
        if 'rtf' in row:
            notes.append(f'x{row["rtf"]:.1f}')
        parts.append(f'{row["phase"]} {row["seconds"]:.1f} s'
                     + (f' ({", ".join(notes)})' if notes else ''))
    rtf = summary.get('achieved_rtf')
    return ('time: ' + ', '.join(parts)
            + ('' if rtf is None else f'; x{rtf:.2f} real time achieved from ready to the '
               'last goal'))


def table_text(summary: dict) -> str:
    """Markdown tables: Table 10 (and 9) per target next to the paper, then summaries."""
    by_key = {(t['name'], t['mode']): t for t in summary['trials']}
    lines = [f'{summary["world"]} simulated world (errors against its ground truth)', '',
             '| target | paper rigid | ours rigid | paper NN | ours predictive '
             '| ours closed loop |',
             '|---|---|---|---|---|---|']

    def ours(name: str, mode: str) -> str:
        t = by_key.get((name, mode))
        if t is None:
            return '-'
        flag = '' if t['error_code'] == 0 else f' (code {t["error_code"]})'
        return f'{t["position_error"] * 1e3:.3f} mm / {math.degrees(t["angle_error"]):.4f}°{flag}'

    def paper(errors: tuple[float, float | None] | None) -> str:
        if errors is None:
            return '-'
        pos, ang = errors
        return f'{pos:.2f} mm / ' + ('-' if ang is None else f'{ang:.4g}°')

    for t in TABLE_10:
        if (t.name, 'rigid') in by_key:
            lines.append(f'| {t.name} {t.target} | {paper(t.rigid_errors)} | '
                         f'{ours(t.name, "rigid")} | {paper(t.compensated_errors)} | '
                         f'{ours(t.name, "predictive")} | {ours(t.name, "closed_loop")} |')
    for name, target, rigid, nn40 in TABLE_9:
        if (name, 'rigid') in by_key:
            lines.append(f'| {name} {target} (Table 9) | {paper(rigid)} | {ours(name, "rigid")}'
                         f' | {paper(nn40)} | {ours(name, "predictive")} | '
                         f'{ours(name, "closed_loop")} |')
    lines += ['', '| group | mode | goals | succeeded | max mm | mean mm | max deg | mean deg |',
              '|---|---|---|---|---|---|---|---|']
    for group, modes in summary['summary'].items():
        for mode, s in modes.items():
            lines.append(f'| {group} | {mode} | {s["count"]} | {s["succeeded"]} | '
                         f'{s["max_mm"]:.3f} | {s["mean_mm"]:.3f} | {s["max_deg"]:.4f} | '
                         f'{s["mean_deg"]:.4f} |')
    return '\n'.join(lines)


def write_summary(summary: dict, out_dir: Path) -> None:
    """``out_dir/summary.json``, written atomically."""
    from flexarm_core.atomic_file import atomic_write

    atomic_write(out_dir / 'summary.json', lambda f: f.write(
        json.dumps(summary, indent=1).encode()))


def write_results(summary: dict, trials: list[Trial], out_dir: Path, geometry: ArmGeometry,
                  regions: dict[str, Region]) -> None:
    """The run's files in ``out_dir``, each written atomically: summary.json, table.md,
    trials.csv (one row per goal), moves.csv (one row per measured move), deflections.csv
    (learning samples and PREDICTIVE goals: measured and predicted deflection), and the
    figures of :mod:`flexarm_recording.results.plots` — errors.png (ours beside the paper),
    deflection_field.png, prediction.png and iterations.png (CLOSED_LOOP goals)."""
    from flexarm_core.atomic_file import atomic_write
    from flexarm_recording.results import plots

    out_dir.mkdir(parents=True, exist_ok=True)
    write_summary(summary, out_dir)
    atomic_write(out_dir / 'table.md', lambda f: f.write(table_text(summary).encode()))
    plots.write_csv(out_dir / 'trials.csv', TRIAL_CSV_FIELDS, [t.csv_row() for t in trials])
    plots.write_csv(out_dir / 'moves.csv', MOVE_CSV_FIELDS,
                    [row for t in trials for row in t.move_rows()])
    panels, sets = [], []
    for name, learned in summary['learning'].items():
        predict, note = plots.model_predict(learned['model_path'])
        joints, deflections, payload = load_dataset(learned['dataset_path']).arrays()
        samples = plots.sample_deflections(name, geometry, joints, deflections, payload,
                                           predict)
        chosen = [t for t in trials if t.region == name]
        targets = {t.name: np.array(t.target) for t in chosen}
        panels.append(plots.field_panel(regions[name], geometry, samples, predict,
                                        float(np.median(payload)) if len(payload) else 0.0,
                                        targets, note=note))
        goals = [t for t in chosen if t.mode == 'predictive' and t.measured is not None]
        sets += [samples, plots.goal_deflections(
            name, [t.name for t in goals], [t.commanded for t in goals],
            [t.measured for t in goals], [t.predicted_deflection for t in goals])]
    plots.write_csv(out_dir / 'deflections.csv', plots.DEFLECTION_CSV_FIELDS,
                    plots.deflection_rows(sets))
    title, tolerance = summary['name'], plots.closed_loop_tolerance()
    plots.save_figure(plots.paper_figure(
        [{'target': t.name, 'mode': t.mode, 'position_error': t.position_error,
          'angle_error': t.angle_error, 'succeeded': t.error_code == 0} for t in trials
         if t.error_code in ACCURACY_CODES],
        tolerance, title), out_dir / 'errors.png')
    if panels:
        plots.save_figure(plots.field_figure(panels, title), out_dir / 'deflection_field.png')
        plots.save_figure(plots.prediction_figure(sets, title), out_dir / 'prediction.png')
    moves = {t.name: [pose_error(t.target, pose)[0] for pose in t.moves]
             for t in trials if t.mode == 'closed_loop' and t.moves}
    if moves:
        plots.save_figure(plots.iteration_figure(moves, tolerance[0], title),
                          out_dir / 'iterations.png')
