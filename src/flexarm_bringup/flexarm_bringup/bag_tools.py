"""Read flexarm bags (MCAP, rosbag2 layout): summary info and the trials' error export.

Bags are read with the ``mcap`` readers and decoded with ``mcap_ros2``, independently of
the writer. A bag whose recorder was killed has no summary or footer: it is read linearly
up to its last complete record (:func:`read_messages`), so every chunk written before the
kill is still there.
"""
from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory

from flexarm_bringup.outcome_text import code_names
from flexarm_control import topics
from flexarm_control.atomic_file import atomic_write
from flexarm_control.kinematics import wrap_angle
from flexarm_msgs.action import MoveToPose

if TYPE_CHECKING:
    from matplotlib.figure import Figure

MCAP_MAGIC = b'\x89MCAP0\r\n'
MODE_NAMES = {getattr(MoveToPose.Goal, name): name.removeprefix('MODE_').lower()
              for name in dir(MoveToPose.Goal) if name.startswith('MODE_')}
ERROR_NAMES = code_names(MoveToPose.Result)
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


def export_trials(path: str | Path, out_dir: str | Path) -> tuple[Path, Path]:
    """Write ``<bag>_trials.csv`` and ``<bag>_trials.png`` of a bag's goal outcomes.

    Returns their paths; ValueError when the bag holds no goal outcome.
    """
    file = mcap_path(path)
    outcomes, truths = [], []
    for topic, msg, _ in read_decoded(file, (topics.OUTCOMES, topics.TIP_POSE_TRUTH)):
        (outcomes if topic == topics.OUTCOMES else truths).append(msg)
    if not outcomes:
        raise ValueError(f'{file} has no {topics.OUTCOMES} messages')
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
