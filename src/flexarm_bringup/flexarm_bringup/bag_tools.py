"""Read flexarm bags (MCAP, rosbag2 layout): summary info, the trials' error export and the
figures of :mod:`flexarm_bringup.plots` the bag's content allows.

Bags are read with the ``mcap`` readers and decoded with ``mcap_ros2``, independently of
the writer. A bag whose recorder was killed has no summary or footer: it is read linearly
up to its last complete record (:func:`read_messages`), so every chunk written before the
kill is still there.

Learning samples (``/learner/samples``) belong to the model announced next on
``/learner/model`` (a collection, then its training); a model announced without new samples
before it (a rollback, a restart) is passed over. Each such model is drawn in the smallest
working region whose box, grown by the learner's coverage margin, holds 80 % of its samples;
the last one per region wins. The bag records each goal's final error only: the per-move
errors of CLOSED_LOOP goals come from the action feedback, which is not recorded, so
``iterations.png`` is written by ``flexarm demo``/``benchmark`` only.
"""
from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory

from flexarm_bringup.outcome_text import code_names
from flexarm_control import topics
from flexarm_control.atomic_file import atomic_write
from flexarm_control.kinematics import ArmGeometry, wrap_angle
from flexarm_control.params import load_config
from flexarm_control.sampling import Region, regions_from_dict
from flexarm_msgs.action import MoveToPose

if TYPE_CHECKING:
    from matplotlib.figure import Figure

MCAP_MAGIC = b'\x89MCAP0\r\n'
MODE_NAMES = {getattr(MoveToPose.Goal, name): name.removeprefix('MODE_').lower()
              for name in dir(MoveToPose.Goal) if name.startswith('MODE_')}
ERROR_NAMES = code_names(MoveToPose.Result)
# goals whose reached pose is an accuracy: the paper comparison draws them
ACCURACY_CODES = (MoveToPose.Result.SUCCESSFUL, MoveToPose.Result.TOLERANCE_NOT_MET)
CSV_FIELDS = (
    'trial', 'mode', 'mode_name', 'error_code', 'error_name', 'succeeded', 'reason',
    'model_version', 'iterations', 'stamp_s', 'data_distance', 'prediction_std_mm',
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


def read_messages(path: str | Path, topic_names: Iterable[str] | None = None
                  ) -> Iterator[tuple[Schema | None, Channel, Message]]:
    """Messages of a bag in file order, also from a truncated file (up to its last record)."""
    wanted = None if topic_names is None else set(topic_names)
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    with open(mcap_path(path), 'rb') as f:
        records = StreamReader(f, skip_magic=False).records
        while True:
            try:
                record = next(records)
            except (StopIteration, EndOfFile):
                return
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels[record.channel_id]
                if wanted is None or channel.topic in wanted:
                    yield schemas.get(channel.schema_id), channel, record


def read_decoded(path: str | Path, topic_names: Iterable[str] | None = None
                 ) -> Iterator[tuple[str, Any, Message]]:
    """``(topic, decoded ROS message, mcap Message)`` of a bag, decoded with mcap_ros2."""
    factory = DecoderFactory()
    decoders: dict[int, Any] = {}
    for schema, channel, message in read_messages(path, topic_names):
        decoder = decoders.get(channel.id)
        if decoder is None:
            decoder = factory.decoder_for(channel.message_encoding, schema)
            decoders[channel.id] = decoder
        yield channel.topic, decoder(message.data), message


def bag_info(path: str | Path) -> dict[str, Any]:
    """Topics (type, count), message count, start/end [ns], duration [s], size of a bag.

    A closed bag is described from its summary; a killed one by reading it through.
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
        for schema, channel, message in read_messages(file):
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


def trial_rows(outcomes: Sequence[Any], truths: Sequence[Any]) -> list[dict[str, Any]]:
    """One row per goal outcome (the columns of :data:`CSV_FIELDS`), in mm and deg.

    ``outcomes`` are GoalOutcome messages, ``truths`` TipPose messages of the simulator's
    ground truth; an outcome's truth is the last valid truth sample stamped at or before the
    outcome's stamp (empty cells when there is none, or when nothing was measured). Errors,
    measured and true alike, are the reached pose minus the target: the position error is the
    distance, the angle error signed and wrapped to (-180, 180] deg. They are left empty for a
    goal that did not move the arm (refused, dry run): its distance from the target is no
    error. ``succeeded`` is False for every goal that did not end SUCCESSFUL; the numbers of
    such a goal are where the arm was left, not an accuracy.
    """
    truth_by_time = sorted(((_stamp_ns(t.header.stamp), t.pose) for t in truths if t.valid),
                           key=lambda item: item[0])
    rows = []
    for outcome in outcomes:
        stamp = _stamp_ns(outcome.stamp)
        earlier = [pose for t, pose in truth_by_time if t <= stamp]
        truth = earlier[-1] if earlier else None
        target = outcome.target
        row: dict[str, Any] = {
            'trial': outcome.trial,
            'mode': outcome.mode,
            'mode_name': MODE_NAMES.get(outcome.mode, str(outcome.mode)),
            'error_code': outcome.error_code,
            'error_name': ERROR_NAMES.get(outcome.error_code, str(outcome.error_code)),
            'succeeded': outcome.error_code == MoveToPose.Result.SUCCESSFUL,
            'reason': outcome.error_string,
            'model_version': getattr(outcome, 'model_version', ''),   # older bags: none
            'iterations': outcome.iterations,
            'stamp_s': stamp * 1e-9,
            'data_distance': outcome.data_distance,
            'prediction_std_mm': outcome.prediction_std * 1e3,
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
    """The bag topics of ``names`` (:mod:`flexarm_control.topics`) of the arm in
    ``namespace`` ('' for a graph without one): full name -> name."""
    return {topics.absolute(name, namespace): name for name in names}


def export_trials(path: str | Path, out_dir: str | Path, namespace: str = ''
                  ) -> tuple[Path, Path]:
    """Write ``<bag>_trials.csv`` and ``<bag>_trials.png`` of a bag's goal outcomes (of the
    arm in ``namespace``).

    Returns their paths; ValueError when the bag holds no goal outcome.
    """
    file = mcap_path(path)
    outcomes, truths = [], []
    names = arm_topics(namespace, topics.OUTCOMES, topics.TIP_POSE_TRUTH)
    for topic, msg, _ in read_decoded(file, names):
        (outcomes if names[topic] == topics.OUTCOMES else truths).append(msg)
    if not outcomes:
        raise ValueError(f'{file} has no {topics.absolute(topics.OUTCOMES, namespace)} '
                         'messages')
    rows = trial_rows(outcomes, truths)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = out_dir / f'{file.stem}_trials.csv'
    text = io.StringIO(newline='')
    writer = csv.DictWriter(text, fieldnames=CSV_FIELDS)
    writer.writeheader()
    writer.writerows(rows)
    atomic_write(csv_path, lambda f: f.write(text.getvalue().encode()))
    png_path = out_dir / f'{file.stem}_trials.png'
    plot_trials(rows, png_path, title=file.stem)
    return csv_path, png_path


def _target_name(trial: str, index: int) -> str:
    """The target of a trial named ``<prefix>/<target>/<mode>``, else the trial's name (or
    ``goal <index>`` for an unnamed goal)."""
    parts = trial.split('/')
    return parts[-2] if len(parts) >= 3 else (trial or f'goal {index}')


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


def export_figures(path: str | Path, out_dir: str | Path, namespace: str = '') -> list[Path]:
    """Write the figures a bag allows and the deflections behind them (module docstring):
    ``<bag>_errors.png`` (goals at the paper's targets), ``<bag>_deflection_field.png``,
    ``<bag>_prediction.png`` and ``<bag>_deflections.csv``. Returns the paths written."""
    from flexarm_bringup import plots

    file = mcap_path(path)
    outcomes, truths, samples, models = [], [], [], []
    names = arm_topics(namespace, topics.OUTCOMES, topics.TIP_POSE_TRUTH, topics.SAMPLES,
                       topics.MODEL)
    for topic, msg, _ in read_decoded(file, names):
        if names[topic] == topics.MODEL:
            models.append((len(samples), msg))
        else:
            {topics.OUTCOMES: outcomes, topics.TIP_POSE_TRUTH: truths,
             topics.SAMPLES: samples}[names[topic]].append(msg)
    geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
    learner = load_config('learner.yaml', node_name='flexarm_learner')
    regions = regions_from_dict(learner['regions'])
    margin = np.asarray(learner['coverage_margin'], dtype=float)
    learned: dict[str, tuple[Any, list[Any]]] = {}
    start = 0
    for end, info in models:
        chosen, start = samples[start:end], end
        region = _region_of(np.array([_xyphi(s.rigid_pose) for s in chosen]), regions,
                            margin) if chosen else None
        if region is not None:
            learned[region] = (info, chosen)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    panels, sets = [], []
    for name, (info, chosen) in learned.items():
        region = regions[name]
        predict, note = plots.model_predict(info.path)
        payload = np.array([s.payload for s in chosen])
        deflections = plots.sample_deflections(
            name, geometry, np.array([s.joint_positions for s in chosen]),
            np.array([_xyphi(s.deflection) for s in chosen]), payload, predict)
        goals = [(i, o) for i, o in enumerate(outcomes)
                 if np.all((np.array(_xyphi(o.target)) >= region.lower)
                           & (np.array(_xyphi(o.target)) <= region.upper))]
        targets = {_target_name(o.trial, i): np.array(_xyphi(o.target)) for i, o in goals}
        panels.append(plots.field_panel(region, geometry, deflections, predict,
                                        float(np.median(payload)), targets, note=note))
        held_out = [(i, o) for i, o in goals if o.mode == MoveToPose.Goal.MODE_PREDICTIVE
                    and o.measured and o.iterations > 0]
        sets += [deflections, plots.goal_deflections(
            name, [o.trial or f'goal {i}' for i, o in held_out],
            [_xyphi(o.commanded_pose) for _, o in held_out],
            [_xyphi(o.measured_pose) for _, o in held_out],
            [_xyphi(o.predicted_deflection) for _, o in held_out])]
    if panels:
        written += [
            plots.save_figure(plots.field_figure(panels, file.stem),
                              out_dir / f'{file.stem}_deflection_field.png'),
            plots.save_figure(plots.prediction_figure(sets, file.stem),
                              out_dir / f'{file.stem}_prediction.png'),
            plots.write_csv(out_dir / f'{file.stem}_deflections.csv',
                            plots.DEFLECTION_CSV_FIELDS, plots.deflection_rows(sets))]
    paper_goals = []
    for i, row in enumerate(trial_rows(outcomes, truths)):
        source = 'truth' if 'truth_position_error_mm' in row else 'measured'
        if f'{source}_position_error_mm' in row and row['error_code'] in ACCURACY_CODES:
            paper_goals.append({
                'target': _target_name(row['trial'], i), 'mode': row['mode_name'],
                'position_error': row[f'{source}_position_error_mm'] * 1e-3,
                'angle_error': math.radians(row[f'{source}_angle_error_deg']),
                'succeeded': row['succeeded']})
    if any(g['target'] in plots.paper_errors() for g in paper_goals):
        written.append(plots.save_figure(
            plots.paper_figure(paper_goals, plots.closed_loop_tolerance(), file.stem),
            out_dir / f'{file.stem}_errors.png'))
    return written


def _error_series(rows: Sequence[dict[str, Any]], quantity: str
                  ) -> tuple[dict[str, tuple[list[int], list[float]]], list[int], list[int]]:
    """What the plot shows of ``quantity`` (``position_error_mm`` or ``angle_error_deg``).

    Returns ``({mode_name: (goal indices, |error|)}, failed goals, goals without an error)``:
    only succeeded goals with an error (true, else measured) are plotted as errors.
    """
    by_mode: dict[str, tuple[list[int], list[float]]] = {}
    failed, unrecorded = [], []
    for i, row in enumerate(rows):
        value = row.get(f'truth_{quantity}', row.get(f'measured_{quantity}'))
        if not row['succeeded']:
            failed.append(i)
        elif value is None:
            unrecorded.append(i)
        else:
            index, values = by_mode.setdefault(row['mode_name'], ([], []))
            index.append(i)
            values.append(abs(value))
    return by_mode, failed, unrecorded


def trials_figure(rows: Sequence[dict[str, Any]], title: str) -> Figure:
    """Position and |angle| error of every succeeded goal by mode on log axes; goals that
    failed, or succeeded without an error (dry runs), as marks along each axis' bottom."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FormatStrFormatter, MaxNLocator, NullFormatter

    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for ax, quantity, label in ((axes[0], 'position_error_mm', 'position error [mm]'),
                                (axes[1], 'angle_error_deg', '|angle error| [deg]')):
        by_mode, failed, unrecorded = _error_series(rows, quantity)
        for mode, (index, values) in by_mode.items():
            ax.plot(index, values, 'o', label=mode)
        for index, marker, color, what in ((failed, 'x', 'red', 'failed goals'),
                                           (unrecorded, '|', 'gray', 'no error recorded')):
            if index:
                ax.plot(index, [0.0] * len(index), marker, color=color, markersize=9,
                        transform=ax.get_xaxis_transform(), clip_on=False,
                        label=f'{what}: {len(index)}')
        ax.set_yscale('log')
        ax.yaxis.set_major_formatter(FormatStrFormatter('%g'))
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[1].set_xlabel('goal')
    axes[1].xaxis.set_major_locator(MaxNLocator(integer=True))
    axes[0].set_title(f'{title}: tip error per goal (truth where recorded, else measured)')
    axes[0].legend(fontsize='small')
    fig.tight_layout()
    return fig


def plot_trials(rows: Sequence[dict[str, Any]], png_path: Path, title: str) -> None:
    """Write :func:`trials_figure` of ``rows`` to ``png_path``."""
    import matplotlib.pyplot as plt

    fig = trials_figure(rows, title)
    atomic_write(png_path, lambda f: fig.savefig(f, dpi=100, format='png'))
    plt.close(fig)
