"""``flexarm bag export`` of a session as an operator runs it: collect, train, calibrate, goals
(one a dry run), then a drift refresh and its retraining, all in one bag."""
from __future__ import annotations

import csv
import gc
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message

from flexarm_cli import main
from flexarm_core import topics
from flexarm_core.kinematics import ArmGeometry, forward
from flexarm_core.paper import TABLE_10
from flexarm_core.params import load_config
from flexarm_core.regions import regions_from_dict
from flexarm_deflection.predictors import make_predictor
from flexarm_deflection.sampling import sample_poses
from flexarm_msgs.action import MoveToPose
from flexarm_msgs.msg import DeflectionSample, GoalOutcome, ModelInfo, PlanarPose, TipPose
from flexarm_recording.bag_tools import (
    calibration_moves,
    export_figures,
    export_trials,
)
from flexarm_recording.bag_writer import BagWriter
from flexarm_recording.results import plots, trial_plots
from flexarm_recording.results.trials import CALIBRATION, DRY_RUN, GOAL

GEOMETRY = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
REGION_A = regions_from_dict(
    load_config('learner.yaml', node_name='flexarm_learner')['regions'])['A']
RIGID, PREDICTIVE = MoveToPose.Goal.MODE_RIGID, MoveToPose.Goal.MODE_PREDICTIVE
SUCCESSFUL = MoveToPose.Result.SUCCESSFUL
TOPICS = {'samples': (topics.SAMPLES, 'DeflectionSample'), 'model': (topics.MODEL, 'ModelInfo'),
          'outcomes': (topics.OUTCOMES, 'GoalOutcome'),
          'truth': (topics.TIP_POSE_TRUTH, 'TipPose')}
OFF_TABLE = np.array([1.5, 0.05, -0.3])       # in region A, no paper target
# (trial, mode, target, moves): what the session sent, in order, between the two trainings
GOALS = ([('', RIGID, t.pose, 1) for t in TABLE_10]                  # flexarm calibrate
         + [('', PREDICTIVE, TABLE_10[0].pose, 1),                   # flexarm move (A1)
            ('', PREDICTIVE, TABLE_10[1].pose, 0),                   # flexarm move --dry-run
            ('', RIGID, OFF_TABLE, 1),
            ('mine', PREDICTIVE, TABLE_10[2].pose, 1)])


def _pose(xyphi: np.ndarray) -> PlanarPose:
    return PlanarPose(x=float(xyphi[0]), y=float(xyphi[1]), phi=float(xyphi[2]))


def _stamp(seconds: float) -> Time:
    return Time(sec=int(seconds), nanosec=int(round(seconds % 1 * 1e9)))


def _sag(joints: np.ndarray) -> np.ndarray:
    """A smooth made-up deflection (N, 3) of joints (N, 4)."""
    return np.column_stack([0.002 * np.sin(joints[:, 0]), -0.01 - 0.01 * joints[:, 1],
                            -0.01 * np.cos(joints[:, 0] + joints[:, 2])])


class _Session:
    """Writes the session's messages into a bag, in the order the recorder would."""

    def __init__(self, writer: BagWriter, models: Path) -> None:
        self.writer, self.models, self.clock = writer, models, 0.0
        self.joints: list[np.ndarray] = []
        for topic, kind in TOPICS.values():
            writer.add_topic(topics.absolute(topic), f'flexarm_msgs/msg/{kind}')

    def write(self, what: str, msg: Any) -> None:
        self.writer.write(topics.absolute(TOPICS[what][0]), serialize_message(msg), 0)

    def collect(self, count: int, seed: int) -> None:
        _, joints = sample_poses(GEOMETRY, REGION_A, count, seed=seed)
        for q, d in zip(joints, _sag(joints)):
            rigid = forward(GEOMETRY, q)
            self.write('samples', DeflectionSample(
                joint_positions=q.tolist(), rigid_pose=_pose(rigid),
                measured_pose=_pose(rigid + d), deflection=_pose(d)))
        self.joints += list(joints)

    def train(self, version: str) -> None:
        path = self.models / f'{version}.model'
        joints = np.array(self.joints)
        make_predictor('rbf').fit(joints, _sag(joints)).save(path)
        self.write('model', ModelInfo(version=version, kind='rbf', path=str(path)))

    def goal(self, trial: str, mode: int, target: np.ndarray, moves: int) -> None:
        reached = target + np.array([2e-5, 0.0, 1e-5])
        self.clock += 1.0
        truth = TipPose(pose=_pose(reached), valid=True)
        truth.header.stamp = _stamp(self.clock)
        self.write('truth', truth)
        self.write('outcomes', GoalOutcome(
            stamp=_stamp(self.clock + 0.5), trial=trial, mode=mode, target=_pose(target),
            commanded_pose=_pose(target), measured=moves > 0,
            measured_pose=_pose(reached if moves else np.zeros(3)), iterations=moves,
            error_code=SUCCESSFUL, error_string='' if moves else 'dry run: nothing moved'))


def _session_bag(tmp_path: Path) -> Path:
    """collect 40, train, calibrate, goals, refresh 8, retrain."""
    (tmp_path / 'models').mkdir()
    bag = tmp_path / 'run'
    with BagWriter(bag) as writer:
        session = _Session(writer, tmp_path / 'models')
        session.collect(40, seed=3)
        session.train('1')
        for goal in GOALS:
            session.goal(*goal)
        session.collect(8, seed=11)
        session.train('2')
    return bag


def _rows(csv_path: Path) -> list[dict[str, str]]:
    with csv_path.open() as f:
        return list(csv.DictReader(f))


def test_export_keeps_dry_runs_and_calibration_moves_apart_and_names_every_trial(
        tmp_path: Path) -> None:
    rows = _rows(export_trials(_session_bag(tmp_path), tmp_path / 'out')[0])
    assert [r['kind'] for r in rows] == [CALIBRATION] * 6 + [GOAL, DRY_RUN, GOAL, GOAL]
    assert [r['trial'] for r in rows] == [
        *(f'calibration/{t.name}/rigid' for t in TABLE_10),
        'run/A1/predictive', 'run/A2/predictive', 'run/goal8/rigid', 'mine']
    assert [r['error_name'] for r in rows] == ['SUCCESSFUL'] * len(GOALS)   # as recorded
    assert [r['succeeded'] for r in rows] == ['True'] * 7 + ['False', 'True', 'True']


def test_trials_figure_marks_dry_runs_apart_and_leaves_calibration_out(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    figures = []
    draw = trial_plots.trials_figure
    monkeypatch.setattr(trial_plots, 'trials_figure',
                        lambda *args: figures.append(draw(*args)) or figures[-1])
    export_trials(_session_bag(tmp_path), tmp_path / 'out')
    for ax in figures[0].axes:
        lines = {line.get_label(): list(line.get_xdata()) for line in ax.get_lines()}
        assert lines == {'predictive': [6, 9], 'rigid': [8], 'dry runs: 1': [7]}


def test_single_untitled_rigid_move_to_a_paper_target_is_a_goal() -> None:
    def outcome(step: int, trial: str = '', mode: int = RIGID) -> GoalOutcome:
        return GoalOutcome(trial=trial, mode=mode, target=_pose(TABLE_10[step].pose))

    assert calibration_moves([outcome(0), outcome(1)]) == set()
    assert calibration_moves([outcome(0), outcome(0), outcome(1), outcome(2)]) == {1, 2, 3}
    assert calibration_moves([outcome(0), outcome(1, 'named'), outcome(2)]) == set()
    assert calibration_moves([outcome(0), outcome(1), outcome(2, mode=PREDICTIVE)]) == set()
    assert calibration_moves([outcome(4, 'calibration/B5/rigid'), outcome(4, 'B5')]) == {0}


def test_figures_draw_every_sample_of_the_run_and_only_reached_goals(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    paper_goals = []
    draw = plots.paper_figure
    monkeypatch.setattr(plots, 'paper_figure',
                        lambda goals, *args: paper_goals.extend(goals) or draw(goals, *args))
    said: list[str] = []
    written = export_figures(_session_bag(tmp_path), tmp_path / 'out', say=said.append)
    assert sorted(p.name for p in written) == [
        'run_deflection_field.png', 'run_deflections.csv', 'run_errors.png',
        'run_prediction.png']
    deflections = _rows(tmp_path / 'out' / 'run_deflections.csv')
    assert [r['source'] for r in deflections].count(plots.SAMPLES) == 48   # 40 + the refresh's 8
    assert [r['label'] for r in deflections if r['source'] == plots.GOALS] == [
        'run/A1/predictive', 'mine']
    assert all(r['predicted_dx_mm'] != '' for r in deflections)      # by the last model
    assert [(g['target'], g['mode']) for g in paper_goals] == [
        ('A1', 'predictive'), ('goal8', 'rigid'), ('A3', 'predictive')]
    assert 'region A: 48 learning samples, model 2' in said
    assert 'drawing run_errors.png' in said
    assert any(s.startswith('run.mcap: ') and 'messages read' in s for s in said)


def test_cli_export_reports_progress_on_stderr(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    bag = _session_bag(tmp_path)
    # What an earlier test of this worker left to the garbage collector prints now, not during
    # the commands judged here: rclpy's never-retrieved task exceptions go to stderr.
    gc.collect()
    capsys.readouterr()
    assert main(['bag', 'export', str(bag), '--out', str(tmp_path / 'out')]) == 0
    out, err = capsys.readouterr()
    assert 'run.mcap: 70 messages read' in err and 'drawing run_trials.png' in err
    assert f'file:   {tmp_path / "out" / "run_errors.png"}' in out
    assert main(['bag', 'export', str(bag), '--out', str(tmp_path / 'q'), '--quiet']) == 0
    assert capsys.readouterr().err == ''


def test_samples_not_yet_trained_are_drawn_without_a_prediction(tmp_path: Path) -> None:
    (tmp_path / 'models').mkdir()
    with BagWriter(tmp_path / 'run') as writer:
        _Session(writer, tmp_path / 'models').collect(10, seed=3)    # canceled before training
    said: list[str] = []
    written = export_figures(tmp_path / 'run', tmp_path / 'out', say=said.append)
    assert 'run_deflection_field.png' in [p.name for p in written]
    deflections = _rows(tmp_path / 'out' / 'run_deflections.csv')
    assert len(deflections) == 10 and all(r['predicted_dx_mm'] == '' for r in deflections)
    assert 'region A: 10 learning samples, model none' in said
