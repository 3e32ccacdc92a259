"""MCAP bags: the pure writer and tools, and the recorder node as its own process.

Bags are read back with the independent ``mcap`` readers and ``mcap_ros2`` decoder.
"""
from __future__ import annotations

import csv
import math
import re
import shutil
import signal
import time
from pathlib import Path
from typing import Any

import pytest
import yaml
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from flexarm_core import topics
from flexarm_msgs.action import MoveToPose
from flexarm_msgs.msg import GoalOutcome, ModelInfo, PlanarPose, TipPose
from flexarm_recording.bag_tools import (
    CSV_FIELDS,
    ERROR_NAMES,
    bag_info,
    export_trials,
    read_messages,
)
from flexarm_recording.bag_writer import BagWriter
from flexarm_recording.results import trial_plots
from flexarm_recording.results.trial_plots import trials_figure

pytestmark = pytest.mark.duration(35)

QOS = {'history': 'keep_last', 'depth': 10, 'reliability': 'reliable',
       'durability': 'transient_local', 'deadline': {'sec': 0, 'nsec': 0},
       'lifespan': {'sec': 0, 'nsec': 0}, 'liveliness': 'automatic',
       'liveliness_lease_duration': {'sec': 0, 'nsec': 0},
       'avoid_ros_namespace_conventions': False}
T0 = 1_700_000_000_000_000_000


def _stamp(ns: int) -> Time:
    return Time(sec=ns // 10**9, nanosec=ns % 10**9)


def _joint_state(i: int) -> bytes:
    return serialize_message(JointState(name=['joint1'], position=[0.001 * i]))


def _decoded(path: Path) -> list[tuple[str, str, Any]]:
    """(topic, schema name, decoded message) of a closed bag, in log time order."""
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [(c.topic, s.name, m) for s, c, _, m in reader.iter_decoded_messages()]


def _stream_messages(path: Path) -> list[Message]:
    """Messages of a possibly truncated file, read with mcap's StreamReader until it ends."""
    messages = []
    with open(path, 'rb') as f:
        try:
            for record in StreamReader(f).records:
                if isinstance(record, Message):
                    messages.append(record)
        except EndOfFile:
            pass
    return messages


def test_written_bag_reads_back_as_rosbag2_mcap(tmp_path: Path) -> None:
    bag = tmp_path / 'trial'
    with BagWriter(bag) as writer:
        writer.add_topic(topics.JOINT_STATES, 'sensor_msgs/msg/JointState', [QOS, QOS])
        writer.add_topic(topics.MODEL, 'flexarm_msgs/msg/ModelInfo', [QOS], type_hash='RIHS01_x')
        writer.add_topic(topics.TIP_POSE, 'flexarm_msgs/msg/TipPose')
        for i in range(25):
            writer.write(topics.JOINT_STATES, _joint_state(i), T0 + i * 10**6)
        writer.write(topics.MODEL, serialize_message(ModelInfo(version='7', kind='mlp')),
                     T0 + 5 * 10**6, publish_time_ns=T0)

    path = bag / 'trial.mcap'
    decoded = _decoded(path)
    assert [t for t, _, _ in decoded].count(topics.JOINT_STATES) == 25
    assert [m.position[0] for t, _, m in decoded if t == topics.JOINT_STATES] == \
        pytest.approx([0.001 * i for i in range(25)])
    [(_, model_type, model)] = [d for d in decoded if d[0] == topics.MODEL]
    assert (model_type, model.version, model.kind) == ('flexarm_msgs/msg/ModelInfo', '7', 'mlp')

    with open(path, 'rb') as f:
        reader = make_reader(f)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        channels = {c.topic: c for c in summary.channels.values()}
        assert {c.message_encoding for c in channels.values()} == {'cdr'}
        assert {s.encoding for s in summary.schemas.values()} == {'ros2msg'}
        assert yaml.safe_load(channels[topics.JOINT_STATES].metadata['offered_qos_profiles']) \
            == [QOS, QOS]
        assert channels[topics.MODEL].metadata['topic_type_hash'] == 'RIHS01_x'
        assert channels[topics.TIP_POSE].metadata == {'offered_qos_profiles': ''}
        [record] = [m for m in reader.iter_metadata() if m.name == 'rosbag2']
    embedded = yaml.safe_load(record.metadata['serialized_metadata'])
    on_disk = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert embedded == on_disk
    assert (on_disk['version'], on_disk['storage_identifier']) == (9, 'mcap')
    assert on_disk['relative_file_paths'] == ['trial.mcap']
    assert on_disk['message_count'] == 26
    assert on_disk['starting_time']['nanoseconds_since_epoch'] == T0
    assert on_disk['duration']['nanoseconds'] == 24 * 10**6
    assert {t['topic_metadata']['name']: t['message_count']
            for t in on_disk['topics_with_message_count']} == \
        {topics.JOINT_STATES: 25, topics.MODEL: 1, topics.TIP_POSE: 0}
    # version 9: rosbag2 decodes the profiles here as a YAML list, not a string
    assert {t['topic_metadata']['name']: t['topic_metadata']['offered_qos_profiles']
            for t in on_disk['topics_with_message_count']} == \
        {topics.JOINT_STATES: [QOS, QOS], topics.MODEL: [QOS], topics.TIP_POSE: []}

    info = bag_info(bag)
    assert info['complete'] and info['rosbag2_metadata']
    assert info['message_count'] == 26
    assert info['topics'][topics.MODEL] == {'type': 'flexarm_msgs/msg/ModelInfo', 'count': 1}


def test_unclosed_bag_is_readable_up_to_its_last_chunk(tmp_path: Path) -> None:
    writer = BagWriter(tmp_path / 'killed', chunk_size=10**9)
    writer.add_topic(topics.JOINT_STATES, 'sensor_msgs/msg/JointState', [QOS])
    for i in range(40):
        writer.write(topics.JOINT_STATES, _joint_state(i), T0 + i)
    writer.flush()
    path = tmp_path / 'killed' / 'killed.mcap'
    first_chunk_end = path.stat().st_size
    for i in range(40, 60):
        writer.write(topics.JOINT_STATES, _joint_state(i), T0 + i)
    writer.flush()
    second_chunk_end = path.stat().st_size
    for i in range(60, 70):                      # still in memory: lost when the process dies
        writer.write(topics.JOINT_STATES, _joint_state(i), T0 + i)

    assert len(_stream_messages(path)) == 60
    cut = tmp_path / 'cut.mcap'                  # died while writing the second chunk
    cut.write_bytes(path.read_bytes()[:(first_chunk_end + second_chunk_end) // 2])
    assert len(_stream_messages(cut)) == 40
    assert [m.log_time - T0 for _, _, m in read_messages(cut)] == list(range(40))
    info = bag_info(path)
    assert not info['complete']
    assert info['topics'] == {topics.JOINT_STATES: {'type': 'sensor_msgs/msg/JointState',
                                                    'count': 60}}
    on_disk = yaml.safe_load((tmp_path / 'killed' / 'metadata.yaml').read_text())
    assert on_disk['rosbag2_bagfile_information']['message_count'] == 60


def test_writer_refuses_an_existing_bag(tmp_path: Path) -> None:
    BagWriter(tmp_path / 'b').close()
    with pytest.raises(FileExistsError):
        BagWriter(tmp_path / 'b')


def _pose(x: float, y: float, phi: float) -> PlanarPose:
    return PlanarPose(x=x, y=y, phi=phi)


def _write_outcome_bag(bag: Path, truths: list[tuple[float, PlanarPose]],
                       outcomes: list[GoalOutcome], namespace: str = '') -> None:
    """A bag of ground-truth tip poses (stamped at ``t`` [s]) and goal outcomes of the arm in
    ``namespace``."""
    truth, outcome_topic = (topics.absolute(t, namespace)
                            for t in (topics.TIP_POSE_TRUTH, topics.OUTCOMES))
    with BagWriter(bag) as writer:
        writer.add_topic(truth, 'flexarm_msgs/msg/TipPose')
        writer.add_topic(outcome_topic, 'flexarm_msgs/msg/GoalOutcome')
        for t, pose in truths:
            msg = TipPose(pose=pose, valid=True)
            msg.header.stamp = _stamp(int(t * 10**9))
            writer.write(truth, serialize_message(msg), T0)
        for outcome in outcomes:
            writer.write(outcome_topic, serialize_message(outcome), T0)


def test_export_trials_pairs_outcomes_with_last_truth(tmp_path: Path) -> None:
    truths = [(1.0, _pose(0.5, 0.2, 0.1)), (2.0, _pose(0.6, 0.3, 0.0)),
              (3.5, _pose(9.0, 9.0, 0.0))]
    outcomes = [
        GoalOutcome(stamp=_stamp(2 * 10**9 + 10), trial='t1', mode=1,
                    target=_pose(0.601, 0.3, 0.01), measured_pose=_pose(0.6005, 0.3, 0.0),
                    measured=True, position_error=0.0005, angle_error=0.01, iterations=1),
        GoalOutcome(stamp=_stamp(10**8), trial='t1', mode=0, target=_pose(0.5, 0.2, 0.0)),
    ]
    _write_outcome_bag(tmp_path / 'run', truths, outcomes, namespace='arm2')
    with pytest.raises(ValueError, match='no /compensator/outcomes'):
        export_trials(tmp_path / 'run', tmp_path / 'out')          # another arm's bag

    csv_path, png_path = export_trials(tmp_path / 'run', tmp_path / 'out', namespace='arm2')
    rows = list(csv.DictReader(csv_path.open()))
    assert [r['mode_name'] for r in rows] == ['predictive', 'rigid']
    first, second = rows
    assert float(first['truth_x_mm']) == pytest.approx(600.0)
    assert float(first['truth_position_error_mm']) == pytest.approx(1.0)
    assert float(first['truth_angle_error_deg']) == pytest.approx(-0.5729578, abs=1e-6)
    assert float(first['measured_position_error_mm']) == pytest.approx(0.5)
    assert float(first['measured_angle_error_deg']) == pytest.approx(-0.5729578, abs=1e-6)
    assert second['truth_x_mm'] == '' and second['measured_x_mm'] == ''
    assert png_path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


Result = MoveToPose.Result
# The names the recorder writes into bags: the full names of the topics.
BAG_JOINTS, BAG_TIP, BAG_MODEL = (topics.absolute(t) for t in (
    topics.JOINT_STATES, topics.TIP_POSE, topics.MODEL))
# (trial, mode, error code, moves, reason, target, measured pose or None, truth); the truths
# are stamped 1 s apart and each outcome 0.5 s after its own.
MIXED_GOALS = [
    ('ok_below', 1, Result.SUCCESSFUL, 1, '', _pose(1.2, -0.1, -0.5),
     _pose(1.20001, -0.1, -0.50002), _pose(1.20002, -0.1, -0.50003)),
    ('refused', 0, Result.UNREACHABLE, 0, 'outside the workspace', _pose(4.0, 0.0, 0.0),
     None, _pose(0.8, 1.4, 0.3)),
    ('canceled', 2, Result.CANCELED, 1, 'canceled; arm held', _pose(1.5, 0.0, 0.0),
     None, _pose(0.9, 0.2, 0.1)),
    ('ok_above', 2, Result.SUCCESSFUL, 2, '', _pose(1.3, 0.2, 0.4),
     _pose(1.3, 0.20003, 0.40001), _pose(1.3, 0.20001, 0.40002)),
    ('dry', 1, Result.SUCCESSFUL, 0, 'dry run: nothing moved', _pose(1.0, 0.5, 0.0),
     None, _pose(1.3, 0.2, 0.4)),
]


def _mixed_bag(bag: Path) -> None:
    truths, outcomes = [], []
    for i, (trial, mode, code, moves, reason, target, measured, truth) in enumerate(
            MIXED_GOALS):
        truths.append((float(i + 1), truth))
        outcomes.append(GoalOutcome(
            stamp=_stamp((2 * i + 3) * 10**9 // 2), trial=trial, mode=mode, target=target,
            measured=measured is not None, measured_pose=measured or PlanarPose(),
            # as the compensator publishes it: |angle error|, whatever its sign
            angle_error=abs(measured.phi - target.phi) if measured else 0.0,
            iterations=moves, error_code=code, error_string=reason,
            model_version='' if mode == 0 else 'gp-7'))
    _write_outcome_bag(bag, truths, outcomes)


def test_export_csv_names_modes_error_codes_reasons_and_models(tmp_path: Path) -> None:
    _mixed_bag(tmp_path / 'mixed')
    csv_path, _ = export_trials(tmp_path / 'mixed', tmp_path / 'out')
    with csv_path.open() as f:
        reader = csv.DictReader(f)
        header, rows = reader.fieldnames, list(reader)
    assert header == list(CSV_FIELDS)
    assert [r['trial'] for r in rows] == [g[0] for g in MIXED_GOALS]
    assert [r['mode_name'] for r in rows] == [
        'predictive', 'rigid', 'closed_loop', 'closed_loop', 'predictive']
    assert [r['error_name'] for r in rows] == [
        'SUCCESSFUL', 'UNREACHABLE', 'CANCELED', 'SUCCESSFUL', 'SUCCESSFUL']
    assert [r['error_code'] for r in rows] == [str(g[2]) for g in MIXED_GOALS]
    assert [r['kind'] for r in rows] == ['goal'] * 4 + ['dry_run']
    assert [r['succeeded'] for r in rows] == ['True', 'False', 'False', 'True', 'False']
    assert [r['reason'] for r in rows] == [g[4] for g in MIXED_GOALS]
    assert [r['model_version'] for r in rows] == ['gp-7', '', 'gp-7', 'gp-7', 'gp-7']
    for row in rows:   # one plain number per cell, in the unit its name carries
        for name in ('target_x_mm', 'target_phi_deg', 'prediction_std_mm', 'stamp_s'):
            float(row[name])
    assert float(rows[3]['target_y_mm']) == pytest.approx(200.0)
    assert float(rows[3]['target_phi_deg']) == pytest.approx(math.degrees(0.4))


def test_every_result_code_of_the_action_has_its_name() -> None:
    action = Path(__file__).parents[2] / 'flexarm_msgs' / 'action' / 'MoveToPose.action'
    result_part = action.read_text().split('---')[1]
    declared = dict(re.findall(r'^int32 (\w+)=(-?\d+)', result_part, re.MULTILINE))
    assert len(declared) >= 9 and declared['OUTSIDE_LEARNED_DATA'] == '-8'
    assert {str(code): name for code, name in ERROR_NAMES.items()} == {
        code: name for name, code in declared.items()}


def test_export_signs_measured_and_true_angle_errors_alike(tmp_path: Path) -> None:
    _mixed_bag(tmp_path / 'mixed')
    rows = list(csv.DictReader(export_trials(tmp_path / 'mixed', tmp_path / 'out')[0].open()))
    below, above = rows[0], rows[3]
    for row, sign in ((below, -1.0), (above, 1.0)):   # reached pose minus target
        measured, truth = float(row['measured_angle_error_deg']), float(
            row['truth_angle_error_deg'])
        assert math.copysign(1.0, measured) == math.copysign(1.0, truth) == sign
    assert float(below['measured_angle_error_deg']) == pytest.approx(
        math.degrees(-0.00002), abs=1e-9)
    assert float(above['truth_angle_error_deg']) == pytest.approx(
        math.degrees(0.00002), abs=1e-9)
    assert float(above['measured_position_error_mm']) == pytest.approx(0.03)


def test_export_never_plots_failed_goals_as_errors(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    figures = []

    def keep(*args: Any, **kwargs: Any) -> Any:
        figures.append(trials_figure(*args, **kwargs))
        return figures[-1]

    monkeypatch.setattr(trial_plots, 'trials_figure', keep)
    _mixed_bag(tmp_path / 'mixed')
    csv_path, png_path = export_trials(tmp_path / 'mixed', tmp_path / 'out')
    rows = list(csv.DictReader(csv_path.open()))
    # the refused goal did not move: its 3.5 m from the target is no error
    assert rows[1]['truth_position_error_mm'] == '' and rows[1]['truth_x_mm'] != ''
    assert rows[4]['truth_position_error_mm'] == ''     # dry run: nothing moved
    assert float(rows[2]['truth_position_error_mm']) > 500   # canceled, arm left there
    assert png_path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'

    (figure,) = figures
    for ax in figure.axes:
        assert ax.get_yscale() == 'log'
        lines = {line.get_label(): line for line in ax.get_lines()}
        assert set(lines) == {'predictive', 'closed_loop', 'failed goals: 2', 'dry runs: 1'}
        assert list(lines['predictive'].get_xdata()) == [0]
        assert list(lines['closed_loop'].get_xdata()) == [3]
        assert list(lines['failed goals: 2'].get_xdata()) == [1, 2]
        assert list(lines['dry runs: 1'].get_xdata()) == [4]
        assert ax.get_ylim()[1] < 1.0     # errors below 0.03 mm / 0.002 deg, not 600+ mm
    position_errors = figure.axes[0].get_lines()[0].get_ydata()
    assert list(position_errors) == pytest.approx([float(rows[0]['truth_position_error_mm'])])
    assert 'failed goals: 2' in [t.get_text() for t in figure.axes[0].get_legend().texts]


# ---- node level: flexarm_recorder as its own process --------------------------------------

N = 150


def _bag_count(bag: Path) -> int:
    """Messages the recorder has flushed to disk (its metadata.yaml, rewritten each flush)."""
    try:
        meta = yaml.safe_load((bag / 'metadata.yaml').read_text())
    except (OSError, yaml.YAMLError):
        return 0
    return (meta or {}).get('rosbag2_bagfile_information', {}).get('message_count', 0)


def _start_and_publish(launch: Any, ros_node: Any, wait_for: Any,
                       bag_dir: Path) -> tuple[Any, Any]:
    """Latch a model, start the recorder of these three topics (not its own /diagnostics,
    whose count depends on time), publish N joint states and tip poses to it."""
    from rclpy.qos import DurabilityPolicy, QoSProfile

    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    model_pub = ros_node.create_publisher(ModelInfo, topics.MODEL, latched)
    model_pub.publish(ModelInfo(version='v1', kind='mlp'))
    joint_pub = ros_node.create_publisher(JointState, topics.JOINT_STATES, 2 * N)
    tip_pub = ros_node.create_publisher(TipPose, topics.TIP_POSE, 2 * N)
    recorder = launch('flexarm_recorder', bag_directory=str(bag_dir), bag_name='t',
                      topics=[topics.JOINT_STATES, topics.TIP_POSE, topics.MODEL],
                      passive_measurements=False)
    wait_for(lambda: all(p.get_subscription_count() for p in (model_pub, joint_pub, tip_pub)),
             20.0, 'the recorder to subscribe to all three topics')
    for i in range(N):
        joint_pub.publish(JointState(name=['joint1'], position=[float(i)]))
        tip_pub.publish(TipPose(pose=_pose(0.001 * i, 0.0, 0.0), valid=True))
    wait_for(lambda: _bag_count(bag_dir / 't') == 2 * N + 1, 20.0,
             f'{2 * N + 1} messages flushed to the bag (log: {recorder.log_path})')
    return recorder, joint_pub


@pytest.mark.node
@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_recorder_closes_bag_with_every_message_on_signal(
        launch: Any, ros_node: Any, wait_for: Any, tmp_path: Path, sig: int) -> None:
    health: dict[str, str] = {}
    ros_node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, lambda m: health.update(
        {v.key: v.value for s in m.status if s.name == 'flexarm_recorder: bag'
         for v in s.values}), 10)
    recorder, _ = _start_and_publish(launch, ros_node, wait_for, tmp_path)
    wait_for(lambda: health.get('messages written') == str(2 * N + 1), 10.0,
             'the messages written on /diagnostics')
    assert health['topics recorded'] == '3' and health['bag'].endswith('t.mcap')
    recorder.signal(sig)
    assert recorder.process.wait(timeout=10.0) == 0, recorder.log_tail()

    decoded = _decoded(tmp_path / 't' / 't.mcap')
    by_topic: dict[str, list[Any]] = {}
    for topic, type_name, msg in decoded:
        by_topic.setdefault(topic, []).append((type_name, msg))
    assert {t: len(v) for t, v in by_topic.items()} == \
        {BAG_JOINTS: N, BAG_TIP: N, BAG_MODEL: 1}
    assert [m.position[0] for _, m in by_topic[BAG_JOINTS]] == \
        [float(i) for i in range(N)]
    assert by_topic[BAG_TIP][0][0] == 'flexarm_msgs/msg/TipPose'
    assert by_topic[BAG_MODEL][0][1].version == 'v1'
    with open(tmp_path / 't' / 't.mcap', 'rb') as f:
        channels = {c.topic: c for c in make_reader(f).get_summary().channels.values()}
    [offered] = yaml.safe_load(channels[BAG_MODEL].metadata['offered_qos_profiles'])
    assert (offered['reliability'], offered['durability']) == ('reliable', 'transient_local')
    assert channels[BAG_TIP].metadata['topic_type_hash'].startswith('RIHS01_')
    info = bag_info(tmp_path / 't')
    assert info['complete'] and info['rosbag2_metadata'] and info['message_count'] == 2 * N + 1
    log_times = [m.log_time for m in _writes(tmp_path / 't' / 't.mcap')]   # taken in batches,
    assert log_times == sorted(log_times)                   # written in receive order


@pytest.mark.node
def test_messages_published_just_before_the_signal_are_recorded(
        launch: Any, ros_node: Any, wait_for: Any, tmp_path: Path) -> None:
    """As the last goal's outcome when a demo stops its graph right after the result."""
    recorder, joint_pub = _start_and_publish(launch, ros_node, wait_for, tmp_path)
    for i in range(N, N + 20):
        joint_pub.publish(JointState(name=['joint1'], position=[float(i)]))
    recorder.signal(signal.SIGINT)
    assert recorder.process.wait(timeout=10.0) == 0, recorder.log_tail()
    positions = [m.position[0] for t, _, m in _decoded(tmp_path / 't' / 't.mcap')
                 if t == BAG_JOINTS]
    assert positions == [float(i) for i in range(N + 20)]


@pytest.mark.node
def test_recorder_bag_survives_sigkill_up_to_its_last_chunk(
        launch: Any, ros_node: Any, wait_for: Any, tmp_path: Path) -> None:
    recorder, joint_pub = _start_and_publish(launch, ros_node, wait_for, tmp_path)
    for i in range(N, 2 * N):                    # may or may not reach the disk
        joint_pub.publish(JointState(name=['joint1'], position=[float(i)]))
    recorder.signal(signal.SIGKILL)
    recorder.process.wait(timeout=10.0)

    path = tmp_path / 't' / 't.mcap'
    kept = tmp_path / 'kept.mcap'
    shutil.copy(path, kept)
    assert not bag_info(kept)['complete']
    messages = _stream_messages(kept)
    assert 2 * N + 1 <= len(messages) <= 3 * N + 1
    factory = DecoderFactory()
    by_topic: dict[str, list[Any]] = {}
    for schema, channel, message in read_messages(kept):
        decode = factory.decoder_for(channel.message_encoding, schema)
        by_topic.setdefault(channel.topic, []).append(decode(message.data))
    positions = [m.position[0] for m in by_topic[BAG_JOINTS]]
    assert positions == [float(i) for i in range(len(positions))]
    assert len(by_topic[BAG_TIP]) == N and len(by_topic[BAG_MODEL]) == 1


def _writes(path: Path) -> list[Message]:
    """The messages of a closed bag in the order they are in the file."""
    with open(path, 'rb') as f:
        return [m for _, _, m in make_reader(f).iter_messages(log_time_order=False)]


@pytest.mark.parametrize('compression', ['zstd', 'lz4', 'none'])
def test_compressed_bag_decodes_fully_with_the_bag_tools(tmp_path: Path,
                                                          compression: str) -> None:
    """Chunks compressed inside the MCAP file: the bag tools and the ROS 2 decoder read every
    message back, the rosbag2 metadata names no file compression."""
    bag = tmp_path / compression
    tips = [TipPose(pose=_pose(0.001 * i, -0.2, 0.1), valid=True) for i in range(50)]
    with BagWriter(bag, chunk_size=4096, compression=compression) as writer:
        writer.add_topic(topics.JOINT_STATES, 'sensor_msgs/msg/JointState', [QOS])
        writer.add_topic(topics.TIP_POSE, 'flexarm_msgs/msg/TipPose', [QOS])
        for i in range(500):
            writer.write(topics.JOINT_STATES, _joint_state(i), T0 + 2 * i)
            if i % 10 == 0:
                writer.write(topics.TIP_POSE, serialize_message(tips[i // 10]), T0 + 2 * i + 1)
    path = bag / f'{compression}.mcap'
    with open(path, 'rb') as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    assert len(chunks) > 3
    assert {c.compression for c in chunks} == {'' if compression == 'none' else compression}
    factory = DecoderFactory()
    decoded: dict[str, list[Any]] = {}
    for schema, channel, message in read_messages(path):
        decode = factory.decoder_for(channel.message_encoding, schema)
        decoded.setdefault(channel.topic, []).append(decode(message.data))
    assert [m.position[0] for m in decoded[topics.JOINT_STATES]] == \
        pytest.approx([0.001 * i for i in range(500)])
    assert [m.pose.x for m in decoded[topics.TIP_POSE]] == [t.pose.x for t in tips]
    assert [t for t, _, _ in _decoded(path)].count(topics.TIP_POSE) == 50
    info = bag_info(bag)
    assert info['complete'] and info['message_count'] == 550
    on_disk = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert (on_disk['compression_format'], on_disk['compression_mode']) == ('', '')


def test_compressed_bag_decodes_fully_with_rosbags(tmp_path: Path) -> None:
    """rosbags reads a zstd bag, every message of it. Its messages are serialized by rosbags
    itself, exactly as they come on the wire: rclpy's serialize_message pads its buffer with
    a few stray bytes, which rosbags' strict CDR reader refuses (a recorded bag's messages,
    taken from the wire, have none)."""
    import numpy as np
    from rosbags import highlevel, typesys

    store = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    joint_state, header, stamp, text = (store.types[name] for name in (
        'sensor_msgs/msg/JointState', 'std_msgs/msg/Header', 'builtin_interfaces/msg/Time',
        'std_msgs/msg/String'))

    def state(i: int) -> bytes:
        return store.serialize_cdr(joint_state(
            header=header(stamp=stamp(sec=i, nanosec=0), frame_id='base_link'),
            name=['joint1'], position=np.array([0.001 * i]), velocity=np.array([0.0]),
            effort=np.array([], dtype=np.float64)), 'sensor_msgs/msg/JointState')

    with BagWriter(tmp_path / 'b', chunk_size=4096) as writer:
        writer.add_topic(topics.JOINT_STATES, 'sensor_msgs/msg/JointState', [QOS])
        writer.add_topic(topics.ROBOT_DESCRIPTION, 'std_msgs/msg/String', [QOS])
        for i in range(300):
            writer.write(topics.JOINT_STATES, state(i), T0 + 2 * i)
            writer.write(topics.ROBOT_DESCRIPTION, store.serialize_cdr(
                text(data=f'<robot name="{i}"/>'), 'std_msgs/msg/String'), T0 + 2 * i + 1)
    with open(tmp_path / 'b' / 'b.mcap', 'rb') as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    assert len(chunks) > 1 and {c.compression for c in chunks} == {'zstd'}
    with highlevel.AnyReader([tmp_path / 'b'], default_typestore=store) as reader:
        read = [(c.topic, reader.deserialize(raw, c.msgtype))
                for c, _, raw in reader.messages()]
    assert [m.position[0] for t, m in read if t == topics.JOINT_STATES] == \
        pytest.approx([0.001 * i for i in range(300)])
    assert [m.data for t, m in read if t == topics.ROBOT_DESCRIPTION] == \
        [f'<robot name="{i}"/>' for i in range(300)]


def test_writer_refuses_an_unknown_compression(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match='zstd'):
        BagWriter(tmp_path / 'b', compression='gzip')
    assert not (tmp_path / 'b').exists()


@pytest.mark.node
def test_a_recording_does_not_make_the_graph_measure(
        launch: Any, ros_node: Any, wait_for: Any, tmp_path: Path, domain_id: int) -> None:
    """The recorder and the state publisher (whose /tf it records) leave /tip_pose alone, so
    the vision node would not measure for the bag; a viewer of /tf asks for it, the recorder
    then records it too, and both leave it when the viewer goes."""
    import rclpy
    from rclpy.context import Context

    from tf2_msgs.msg import TFMessage

    tip_pub = ros_node.create_publisher(TipPose, topics.TIP_POSE, 100)    # the vision node's
    launch('flexarm_state_publisher')
    recorder = launch('flexarm_recorder', bag_directory=str(tmp_path), bag_name='p',
                      discovery_period=0.1)

    def consumers() -> set[str]:
        return {i.node_name for i in ros_node.get_subscriptions_info_by_topic(topics.TIP_POSE)}

    wait_for(lambda: 'flexarm_recorder' in {
        i.node_name for i in ros_node.get_subscriptions_info_by_topic(topics.TF)},
        20.0, 'the recorder to subscribe to /tf')
    wait_for(lambda: 'flexarm_state_publisher' in {
        i.node_name for i in ros_node.get_subscriptions_info_by_topic(topics.JOINT_STATES)},
        20.0, 'the state publisher to take /joint_states for the recorder')
    deadline = time.monotonic() + 1.5                # a dozen discovery passes
    while time.monotonic() < deadline:
        assert not consumers(), 'a recording asked for the measured tip'
        tip_pub.publish(TipPose(pose=_pose(-1.0, 0.0, 0.0), valid=True))   # nobody's
        time.sleep(0.05)

    context = Context()                              # a viewer: rviz on /tf
    rclpy.init(context=context, domain_id=domain_id)
    viewer = rclpy.create_node('viewer', context=context)
    viewer.create_subscription(TFMessage, topics.TF, lambda _: None, 100)
    try:
        wait_for(lambda: consumers() == {'flexarm_state_publisher', 'flexarm_recorder'},
                 20.0, 'the state publisher and then the recorder on /tip_pose')
        for i in range(20):
            tip_pub.publish(TipPose(pose=_pose(0.001 * i, 0.0, 0.0), valid=True))
            time.sleep(0.01)
        time.sleep(0.5)                              # taken and written (take_period 0.1 s)
    finally:
        viewer.destroy_node()
        rclpy.try_shutdown(context=context)
    wait_for(lambda: not consumers(), 20.0, 'both to leave /tip_pose with the viewer')
    recorder.signal(signal.SIGINT)
    assert recorder.process.wait(timeout=10.0) == 0, recorder.log_tail()
    recorded = [m.pose.x for t, _, m in _decoded(tmp_path / 'p' / 'p.mcap') if t == BAG_TIP]
    assert recorded == pytest.approx([0.001 * i for i in range(20)])
