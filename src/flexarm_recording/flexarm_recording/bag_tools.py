"""Read flexarm bags (MCAP, rosbag2 layout): summary info, the trials' error export and the
figures of :mod:`flexarm_recording.results.plots` the bag's content allows.

Bags are read with the ``mcap`` readers and decoded with ``mcap_ros2``, independently of
the writer. A bag whose recorder was killed has no summary or footer: it is read linearly
up to its last complete record (:func:`read_messages`), so every chunk written before the
kill is still there.

Learning samples (``/learner/samples``) are taken in batches, each ended by the model
announced next on ``/learner/model`` (a collection, then its training; a refresh, then its
retraining); a model announced without new samples before it (a rollback, a restart) is
passed over. Each batch belongs to the smallest working region whose box, grown by the
learner's coverage margin, holds 80 % of its samples. A region is drawn with every sample of
the run in it and its last model: a refresh adds to the collection, it does not replace it.
The bag records each goal's final error only: the per-move errors of CLOSED_LOOP goals come
from the action feedback, which is not recorded, so ``iterations.png`` is written by
``flexarm demo``/``benchmark`` only.

Not every goal outcome is a goal reached (column ``kind``): a dry run only planned (the bag
has no dry-run flag: a goal that succeeded without a move can only be one), and the moves of
``flexarm calibrate`` (untitled RIGID goals to the Table 10 poses, in the table's order) only
serve the camera's calibration. Both stay in the CSV but out of the goal figures. Untitled
goals are named as :func:`flexarm_recording.results.trials.trial_name` names trials, after the
paper target at their pose if any.
"""
from __future__ import annotations

import csv
import io
import math
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory

from flexarm_bringup.launcher import node_name
from flexarm_core import topics
from flexarm_core.atomic_file import atomic_write
from flexarm_core.kinematics import ArmGeometry, wrap_angle
from flexarm_core.paper import TABLE_9, TABLE_10
from flexarm_core.params import load_config
from flexarm_core.regions import Region, configured_regions
from flexarm_msgs.action import MoveToPose
from flexarm_recording.results.outcome_text import code_names
from flexarm_recording.results.trials import CALIBRATION, DRY_RUN, GOAL, trial_name, trial_target

MCAP_MAGIC = b'\x89MCAP0\r\n'
MODE_NAMES = {getattr(MoveToPose.Goal, name): name.removeprefix('MODE_').lower()
              for name in dir(MoveToPose.Goal) if name.startswith('MODE_')}
ERROR_NAMES = code_names(MoveToPose.Result)
# goals whose reached pose is an accuracy: the paper comparison draws them
ACCURACY_CODES = (MoveToPose.Result.SUCCESSFUL, MoveToPose.Result.TOLERANCE_NOT_MET)
# what an outcome is (module docstring): only GOAL rows are goals of the statistics and figures
MIN_CALIBRATION_MOVES = 3       # flexarm calibrate needs 3 measured poses of its 6
POSE_MATCH = 1e-6               # [m], [rad]: a goal sent to a paper target is at it
PROGRESS_PERIOD = 2.0           # [s] between reports of messages read
CSV_FIELDS = (
    'trial', 'kind', 'mode', 'mode_name', 'error_code', 'error_name', 'succeeded', 'reason',
    'model_version', 'iterations', 'stamp_s', 'data_distance', 'prediction_std_mm',
    'position_error_bound_mm', 'angle_error_bound_deg', 'mode_run',
    'target_x_mm', 'target_y_mm', 'target_phi_deg',
    'measured', 'measured_x_mm', 'measured_y_mm', 'measured_phi_deg',
    'measured_position_error_mm', 'measured_angle_error_deg',
    'truth_x_mm', 'truth_y_mm', 'truth_phi_deg',
    'truth_position_error_mm', 'truth_angle_error_deg')


def mcap_path(path: str | Path) -> Path:
    """The MCAP file of a bag given as its directory or as the file itself."""
    path = Path(path)
    if path.is_dir():
        named = path / f'{path.name}.mcap'
        found = [named] if named.is_file() else sorted(path.glob('*.mcap'))
        if not found:
            raise FileNotFoundError(f'no .mcap file in {path}')
        return found[0]
    if not path.is_file():
        raise FileNotFoundError(f'no bag at {path}')
    return path


def is_complete(path: str | Path) -> bool:
    """Whether the MCAP file ends with its closing magic (it was closed, not killed)."""
    path = mcap_path(path)
    with open(path, 'rb') as f:
        if path.stat().st_size < 2 * len(MCAP_MAGIC):
            return False
        f.seek(-len(MCAP_MAGIC), 2)
        return f.read() == MCAP_MAGIC


def _silent(text: str) -> None:
    """The default progress report: none."""


def read_messages(path: str | Path, topic_names: Iterable[str] | None = None,
                  say: Callable[[str], None] = _silent,
                  ) -> Iterator[tuple[Schema | None, Channel, Message]]:
    """Messages of a bag in file order, also from a truncated file (up to its last record).

    ``say`` hears every :data:`PROGRESS_PERIOD` how far the reading is: a large bag (camera
    images) takes a while to read through."""
    wanted = None if topic_names is None else set(topic_names)
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    file = mcap_path(path)
    size_mib = file.stat().st_size / 2**20
    count, reported = 0, time.monotonic()
    with open(file, 'rb') as f:
        records = StreamReader(f, skip_magic=False).records
        while True:
            try:
                record = next(records)
            except (StopIteration, EndOfFile):
                say(f'{file.name}: {count} messages read')
                return
            if time.monotonic() - reported >= PROGRESS_PERIOD:
                reported = time.monotonic()
                say(f'{file.name}: {count} messages read, {f.tell() / 2**20:.0f} of '
                    f'{size_mib:.0f} MiB')
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                count += 1
                channel = channels[record.channel_id]
                if wanted is None or channel.topic in wanted:
                    yield schemas.get(channel.schema_id), channel, record


def read_decoded(path: str | Path, topic_names: Iterable[str] | None = None,
                 say: Callable[[str], None] = _silent) -> Iterator[tuple[str, Any, Message]]:
    """``(topic, decoded ROS message, mcap Message)`` of a bag, decoded with mcap_ros2."""
    factory = DecoderFactory()
    decoders: dict[int, Any] = {}
    for schema, channel, message in read_messages(path, topic_names, say):
        decoder = decoders.get(channel.id)
        if decoder is None:
            decoder = factory.decoder_for(channel.message_encoding, schema)
            decoders[channel.id] = decoder
        yield channel.topic, decoder(message.data), message


def bag_info(path: str | Path, say: Callable[[str], None] = _silent) -> dict[str, Any]:
    """Topics (type, count), message count, start/end [ns], duration [s], size of a bag.

    A closed bag is described from its summary; a killed one by reading it through (``say``
    hears how far).
    """
    file = mcap_path(path)
    complete = is_complete(file)
    counts: dict[int, int] = {}
    channels: dict[int, Channel] = {}
    schemas: dict[int, Schema] = {}
    start = end = None
    rosbag2_metadata = False
    if complete:
        with open(file, 'rb') as f:
            reader = make_reader(f)
            summary = reader.get_summary()
            if summary is not None and summary.statistics is not None:
                stats = summary.statistics
                channels, schemas = dict(summary.channels), dict(summary.schemas)
                counts = dict(stats.channel_message_counts)
                if stats.message_count:
                    start, end = stats.message_start_time, stats.message_end_time
            rosbag2_metadata = any(m.name == 'rosbag2' for m in reader.iter_metadata())
    if not channels:
        for schema, channel, message in read_messages(file, say=say):
            channels[channel.id] = channel
            if schema is not None:
                schemas[schema.id] = schema
            counts[channel.id] = counts.get(channel.id, 0) + 1
            start = message.log_time if start is None else min(start, message.log_time)
            end = message.log_time if end is None else max(end, message.log_time)
    topic_info = {
        c.topic: {'type': schemas[c.schema_id].name if c.schema_id in schemas else '',
                  'count': counts.get(cid, 0)}
        for cid, c in sorted(channels.items())}
    return {
        'path': str(file),
        'size_bytes': file.stat().st_size,
        'complete': complete,
        'rosbag2_metadata': rosbag2_metadata,
        'message_count': sum(t['count'] for t in topic_info.values()),
        'start_ns': start,
        'end_ns': end,
        'duration_s': 0.0 if start is None else (end - start) * 1e-9,
        'topics': topic_info,
    }


def format_bag_info(info: dict[str, Any]) -> str:
    """Human-readable lines of :func:`bag_info`, like ``ros2 bag info``."""
    lines = [f'File:      {info["path"]}',
             f'Size:      {info["size_bytes"] / 2**20:.2f} MiB'
             + ('' if info['complete'] else '  (not closed: read up to its last chunk)'),
             f'Duration:  {info["duration_s"]:.3f} s',
             f'Messages:  {info["message_count"]}']
    width = max((len(t) for t in info['topics']), default=0)
    for topic, t in info['topics'].items():
        lines.append(f'  {topic:<{width}}  {t["count"]:>8}  {t["type"]}')
    return '\n'.join(lines)


def _stamp_ns(stamp: Any) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _pose_mm_deg(prefix: str, pose: Any) -> dict[str, float]:
    return {f'{prefix}_x_mm': pose.x * 1e3, f'{prefix}_y_mm': pose.y * 1e3,
            f'{prefix}_phi_deg': math.degrees(pose.phi)}


def _errors_mm_deg(prefix: str, pose: Any, target: Any) -> dict[str, float]:
    """Position error [mm] and signed angle error [deg] of ``pose``: pose minus target."""
    return {f'{prefix}_position_error_mm': math.hypot(pose.x - target.x, pose.y - target.y) * 1e3,
            f'{prefix}_angle_error_deg': math.degrees(wrap_angle(pose.phi - target.phi))}


def paper_targets() -> dict[str, np.ndarray]:
    """The targets of the paper's Tables 10 and 9 by name [m, m, rad]."""
    targets = {t.name: t.pose for t in TABLE_10}
    targets.update({name: np.array([x / 1e3, y / 1e3, math.radians(phi)])
                    for name, (x, y, phi), _, _ in TABLE_9})
    return targets


def _at(pose: Any, target: np.ndarray) -> bool:
    return bool(np.allclose(_xyphi(pose), target, rtol=0.0, atol=POSE_MATCH))


def paper_target_at(pose: Any) -> str | None:
    """The name of the paper's target at ``pose`` (a PlanarPose), None if it is none."""
    return next((name for name, target in paper_targets().items() if _at(pose, target)), None)


def _calibration_step(outcome: Any, step: int) -> bool:
    """Whether ``outcome`` can be move ``step`` of ``flexarm calibrate``: untitled, RIGID,
    at the Table 10 pose of that step."""
    return (not outcome.trial and outcome.mode == MoveToPose.Goal.MODE_RIGID
            and step < len(TABLE_10) and _at(outcome.target, TABLE_10[step].pose))


def calibration_moves(outcomes: Sequence[Any]) -> set[int]:
    """Indices of the outcomes of calibration moves: those of trials named
    ``calibration/<target>/<mode>``, and runs of at least :data:`MIN_CALIBRATION_MOVES`
    untitled RIGID goals to the Table 10 poses in the table's order, as ``flexarm calibrate``
    sends them (without a trial name: the bag has no other mark of them)."""
    found = {i for i, o in enumerate(outcomes) if o.trial.startswith(f'{CALIBRATION}/')}
    run: list[int] = []
    for i, outcome in enumerate(outcomes):
        if not _calibration_step(outcome, len(run)):
            found.update(run if len(run) >= MIN_CALIBRATION_MOVES else ())
            run = []
        if _calibration_step(outcome, len(run)):
            run.append(i)
    found.update(run if len(run) >= MIN_CALIBRATION_MOVES else ())
    return found


def goal_kinds(outcomes: Sequence[Any]) -> list[str]:
    """:data:`GOAL`, :data:`DRY_RUN` or :data:`CALIBRATION` per outcome (module docstring)."""
    calibration = calibration_moves(outcomes)
    return [CALIBRATION if i in calibration
            else DRY_RUN if o.error_code == MoveToPose.Result.SUCCESSFUL and o.iterations == 0
            else GOAL for i, o in enumerate(outcomes)]


def _trial_of(outcome: Any, index: int, kind: str, prefix: str) -> str:
    """The goal's trial name; an untitled goal's as :func:`trial_name` makes it, under
    ``prefix`` (calibration moves under ``calibration``), after the paper target at its pose
    (else ``goal<index>``)."""
    if outcome.trial:
        return outcome.trial
    target = paper_target_at(outcome.target) or f'goal{index}'
    return trial_name(CALIBRATION if kind == CALIBRATION else prefix, target,
                      MODE_NAMES.get(outcome.mode, str(outcome.mode)))


def trial_rows(outcomes: Sequence[Any], truths: Sequence[Any], prefix: str
               ) -> list[dict[str, Any]]:
    """One row per goal outcome (the columns of :data:`CSV_FIELDS`), in mm and deg.

    ``outcomes`` are GoalOutcome messages, ``truths`` TipPose messages of the simulator's
    ground truth; an outcome's truth is the last valid truth sample stamped at or before the
    outcome's stamp (empty cells when there is none, or when nothing was measured). Errors,
    measured and true alike, are the reached pose minus the target: the position error is the
    distance, the angle error signed and wrapped to (-180, 180] deg. They are left empty for a
    goal that did not move the arm (refused, dry run): its distance from the target is no
    error. ``succeeded`` is False for every goal that did not end SUCCESSFUL, and for a dry
    run (it reached nothing); the numbers of such a goal are where the arm was left, not an
    accuracy. ``kind`` tells goals from dry runs and calibration moves (:func:`goal_kinds`);
    untitled goals are named under ``prefix`` (:func:`_trial_of`).
    """
    truth_by_time = sorted(((_stamp_ns(t.header.stamp), t.pose) for t in truths if t.valid),
                           key=lambda item: item[0])
    rows = []
    for index, (outcome, kind) in enumerate(zip(outcomes, goal_kinds(outcomes))):
        stamp = _stamp_ns(outcome.stamp)
        earlier = [pose for t, pose in truth_by_time if t <= stamp]
        truth = earlier[-1] if earlier else None
        target = outcome.target
        row: dict[str, Any] = {
            'trial': _trial_of(outcome, index, kind, prefix),
            'kind': kind,
            'mode': outcome.mode,
            'mode_name': MODE_NAMES.get(outcome.mode, str(outcome.mode)),
            'error_code': outcome.error_code,
            'error_name': ERROR_NAMES.get(outcome.error_code, str(outcome.error_code)),
            'succeeded': outcome.error_code == MoveToPose.Result.SUCCESSFUL
            and kind != DRY_RUN,
            'reason': outcome.error_string,
            'model_version': getattr(outcome, 'model_version', ''),   # older bags: none
            'iterations': outcome.iterations,
            'stamp_s': stamp * 1e-9,
            'data_distance': outcome.data_distance,
            'prediction_std_mm': outcome.prediction_std * 1e3,
            'position_error_bound_mm': getattr(outcome, 'position_error_bound',   # older bags
                                               math.nan) * 1e3,
            'angle_error_bound_deg': math.degrees(getattr(outcome, 'angle_error_bound',
                                                          math.nan)),
            'mode_run': MODE_NAMES.get(getattr(outcome, 'mode_run', outcome.mode), ''),
            **_pose_mm_deg('target', target),
            'measured': outcome.measured,
        }
        if outcome.measured:
            row.update(_pose_mm_deg('measured', outcome.measured_pose))
            row.update(_errors_mm_deg('measured', outcome.measured_pose, target))
        if truth is not None:
            row.update(_pose_mm_deg('truth', truth))
            if outcome.iterations > 0:
                row.update(_errors_mm_deg('truth', truth, target))
        rows.append(row)
    return rows


def arm_topics(namespace: str, *names: str) -> dict[str, str]:
    """The bag topics of ``names`` (:mod:`flexarm_core.topics`) of the arm in
    ``namespace`` ('' for a graph without one): full name -> name."""
    return {topics.absolute(name, namespace): name for name in names}


def export_trials(path: str | Path, out_dir: str | Path, namespace: str = '',
                  say: Callable[[str], None] = _silent) -> tuple[Path, Path]:
    """Write ``<bag>_trials.csv`` and ``<bag>_trials.png`` of a bag's goal outcomes (of the
    arm in ``namespace``); untitled goals are named under the bag's name, as trials of a
    demo are. ``say`` hears the progress.

    Returns their paths; ValueError when the bag holds no goal outcome.
    """
    file = mcap_path(path)
    outcomes, truths = [], []
    names = arm_topics(namespace, topics.OUTCOMES, topics.TIP_POSE_TRUTH)
    for topic, msg, _ in read_decoded(file, names, say):
        (outcomes if names[topic] == topics.OUTCOMES else truths).append(msg)
    if not outcomes:
        raise ValueError(f'{file} has no {topics.absolute(topics.OUTCOMES, namespace)} '
                         'messages')
    rows = trial_rows(outcomes, truths, file.stem)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = out_dir / f'{file.stem}_trials.csv'
    say(f'writing {csv_path.name} ({len(rows)} goal outcomes)')
    text = io.StringIO(newline='')
    writer = csv.DictWriter(text, fieldnames=CSV_FIELDS)
    writer.writeheader()
    writer.writerows(rows)
    atomic_write(csv_path, lambda f: f.write(text.getvalue().encode()))
    png_path = out_dir / f'{file.stem}_trials.png'
    say(f'drawing {png_path.name}')
    from flexarm_recording.results.trial_plots import plot_trials  # matplotlib, when asked

    plot_trials(rows, png_path, title=file.stem)
    return csv_path, png_path


def _target_name(outcome: Any, trial: str) -> str:
    """What a goal aimed at: the paper target at its pose, else the target of its ``trial``
    name (:func:`trial_target`), else that name."""
    return paper_target_at(outcome.target) or trial_target(trial) or trial


def _xyphi(pose: Any) -> list[float]:
    return [pose.x, pose.y, pose.phi]


def _region_of(poses: np.ndarray, regions: dict[str, Region], margin: np.ndarray,
               share: float = 0.8) -> str | None:
    """The smallest region whose box grown by ``margin`` holds ``share`` of ``poses`` (N, 3)."""
    holding = []
    for name, region in regions.items():
        grown = region.grown(margin)
        inside = np.all((poses >= grown.lower) & (poses <= grown.upper), axis=1)
        if inside.mean() >= share:
            holding.append((float(np.prod((region.upper - region.lower)[:2])), name))
    return min(holding)[1] if holding else None


def learned_regions(samples: Sequence[Any], models: Sequence[tuple[int, Any]],
                    regions: dict[str, Region], margin: np.ndarray
                    ) -> dict[str, tuple[Any | None, list[Any]]]:
    """Per region: its last model (None if none was announced after its samples) and every
    learning sample of the run in it (module docstring). ``models`` are ``(number of samples
    before it, ModelInfo)``; samples after the last model are drawn too."""
    learned: dict[str, tuple[Any | None, list[Any]]] = {}
    start = 0
    for end, info in [*models, (len(samples), None)]:
        chosen, start = samples[start:end], max(start, end)
        region = _region_of(np.array([_xyphi(s.rigid_pose) for s in chosen]), regions,
                            margin) if chosen else None
        if region is not None:
            last, earlier = learned.get(region, (None, []))
            learned[region] = (info or last, earlier + chosen)
    return learned


def _in_box(pose: Any, region: Region) -> bool:
    xyphi = np.array(_xyphi(pose))
    return bool(np.all((xyphi >= region.lower) & (xyphi <= region.upper)))


def _paper_goals(rows: Sequence[dict[str, Any]], outcomes: Sequence[Any]
                 ) -> list[dict[str, Any]]:
    """The goals (not dry runs or calibration moves) of :func:`plots.paper_figure` whose pose
    reached is an accuracy: error from the truth where recorded, else as measured."""
    goals = []
    for row, outcome in zip(rows, outcomes):
        source = 'truth' if 'truth_position_error_mm' in row else 'measured'
        if (row['kind'] == GOAL and f'{source}_position_error_mm' in row
                and row['error_code'] in ACCURACY_CODES):
            goals.append({
                'target': _target_name(outcome, row['trial']), 'mode': row['mode_name'],
                'position_error': row[f'{source}_position_error_mm'] * 1e-3,
                'angle_error': math.radians(row[f'{source}_angle_error_deg']),
                'succeeded': row['succeeded']})
    return goals


def export_figures(path: str | Path, out_dir: str | Path, namespace: str = '',
                   say: Callable[[str], None] = _silent) -> list[Path]:
    """Write the figures a bag allows and the deflections behind them (module docstring):
    ``<bag>_errors.png`` (goals at the paper's targets), ``<bag>_deflection_field.png``,
    ``<bag>_prediction.png`` and ``<bag>_deflections.csv``; ``say`` hears the progress.
    Returns the paths written."""
    from flexarm_recording.results import plots

    file = mcap_path(path)
    outcomes, truths, samples, models = [], [], [], []
    names = arm_topics(namespace, topics.OUTCOMES, topics.TIP_POSE_TRUTH, topics.SAMPLES,
                       topics.MODEL)
    for topic, msg, _ in read_decoded(file, names, say):
        if names[topic] == topics.MODEL:
            models.append((len(samples), msg))
        else:
            {topics.OUTCOMES: outcomes, topics.TIP_POSE_TRUTH: truths,
             topics.SAMPLES: samples}[names[topic]].append(msg)
    geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
    learner = load_config('learner.yaml', node_name=node_name('learner'))
    regions = configured_regions(node_name('learner'))
    margin = np.asarray(learner['coverage_margin'], dtype=float)
    rows = trial_rows(outcomes, truths, file.stem)
    reached = [(i, o) for i, (o, row) in enumerate(zip(outcomes, rows)) if row['kind'] == GOAL]
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    panels, sets = [], []
    for name, (info, chosen) in learned_regions(samples, models, regions, margin).items():
        region = regions[name]
        say(f'region {name}: {len(chosen)} learning samples, model '
            f'{info.version if info else "none"}')
        predict, note = (plots.model_predict(info.path) if info is not None
                         else (None, 'no model trained after these samples'))
        payload = np.array([s.payload for s in chosen])
        deflections = plots.sample_deflections(
            name, geometry, np.array([s.joint_positions for s in chosen]),
            np.array([_xyphi(s.deflection) for s in chosen]), payload, predict)
        goals = [(i, o) for i, o in reached if _in_box(o.target, region)]
        targets = {_target_name(o, rows[i]['trial']): np.array(_xyphi(o.target)) for i, o in goals}
        panels.append(plots.field_panel(region, geometry, deflections, predict,
                                        float(np.median(payload)), targets, note=note))
        held_out = [(i, o) for i, o in goals if o.mode == MoveToPose.Goal.MODE_PREDICTIVE
                    and o.measured and o.iterations > 0]
        sets += [deflections, plots.goal_deflections(
            name, [rows[i]['trial'] for i, _ in held_out],
            [_xyphi(o.commanded_pose) for _, o in held_out],
            [_xyphi(o.measured_pose) for _, o in held_out],
            [_xyphi(o.predicted_deflection) for _, o in held_out])]
    if panels:
        say(f'drawing {file.stem}_deflection_field.png')
        written.append(plots.save_figure(plots.field_figure(panels, file.stem),
                                         out_dir / f'{file.stem}_deflection_field.png'))
        say(f'drawing {file.stem}_prediction.png')
        written += [
            plots.save_figure(plots.prediction_figure(sets, file.stem),
                              out_dir / f'{file.stem}_prediction.png'),
            plots.write_csv(out_dir / f'{file.stem}_deflections.csv',
                            plots.DEFLECTION_CSV_FIELDS, plots.deflection_rows(sets))]
    paper_goals = _paper_goals(rows, outcomes)
    if any(g['target'] in plots.paper_errors() for g in paper_goals):
        say(f'drawing {file.stem}_errors.png')
        written.append(plots.save_figure(
            plots.paper_figure(paper_goals, plots.closed_loop_tolerance(), file.stem),
            out_dir / f'{file.stem}_errors.png'))
    return written
