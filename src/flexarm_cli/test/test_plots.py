"""The run's figures and CSV tables: each figure from small synthetic data, the demo's result
files, and the figures of a bag."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from matplotlib.quiver import Quiver, QuiverKey
from rclpy.serialization import serialize_message

from flexarm_cli.experiment import write_results
from flexarm_core import topics
from flexarm_core.kinematics import ArmGeometry, forward, inverse
from flexarm_core.params import load_config
from flexarm_core.regions import Region, regions_from_dict
from flexarm_deflection.dataset import DatasetWriter, Sample
from flexarm_deflection.predictors import make_predictor
from flexarm_deflection.sampling import sample_poses
from flexarm_msgs.msg import DeflectionSample, GoalOutcome, ModelInfo, PlanarPose, TipPose
from flexarm_recording.bag_tools import export_figures
from flexarm_recording.bag_writer import BagWriter
from flexarm_recording.results import plots
from flexarm_recording.results.trials import MOVE_CSV_FIELDS, TRIAL_CSV_FIELDS, Trial, summarise

GEOMETRY = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
REGIONS = regions_from_dict(load_config('learner.yaml', node_name='flexarm_learner')['regions'])
TOLERANCE = (5e-5, math.radians(0.005))
PNG = b'\x89PNG\r\n\x1a\n'


def sag(joints: np.ndarray, payload: np.ndarray | None = None) -> np.ndarray:
    """A smooth made-up deflection (N, 3) [m, m, rad] of joints (N, 4): 10-25 mm down."""
    q = np.atleast_2d(joints)
    return np.column_stack([0.002 * np.sin(q[:, 0]), -0.01 - 0.01 * np.cos(q[:, 0]) * q[:, 1],
                            -0.01 * np.cos(q[:, 0] + q[:, 2])])


def samples_of(name: str, count: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Joints (count, 4) of reachable poses of region ``name`` and their deflections."""
    _, joints = sample_poses(GEOMETRY, REGIONS[name], count, seed=3)
    return joints, sag(joints)


def test_field_figure_draws_measured_and_predicted_arrows_per_region() -> None:
    panels = []
    for name in ('A', 'B'):
        joints, deflections = samples_of(name)
        samples = plots.sample_deflections(name, GEOMETRY, joints, deflections,
                                           np.zeros(len(joints)), sag)
        targets = {'T1': np.array([1.45, -0.15, math.radians(-45)])} if name == 'A' else {}
        panels.append(plots.field_panel(REGIONS[name], GEOMETRY, samples, sag, 0.0, targets,
                                        points=5))
    fig = plots.field_figure(panels, 'run')
    assert len(fig.axes) == 2
    for ax, panel in zip(fig.axes, panels):
        assert ax.get_xlabel() == 'x [mm]' and ax.get_ylabel() == 'y (up) [mm]'
        quivers = [c for c in ax.collections if isinstance(c, Quiver)]
        assert [q.N for q in quivers] == [len(panel.grid), 12]       # grid, then samples
        assert 0 < len(panel.grid) <= 25
        predicted = sag(np.array([inverse(GEOMETRY, p) for p in panel.grid]))
        assert np.asarray(quivers[0].U) == pytest.approx(predicted[:, 0] * 1e3)   # in mm
        assert np.asarray(quivers[1].V) == pytest.approx(panel.samples.measured[:, 1] * 1e3)
        assert np.c_[quivers[1].X, quivers[1].Y] == pytest.approx(
            forward(GEOMETRY, samples_of(panel.region.name)[0])[:, :2] * 1e3)
        assert any(isinstance(a, QuiverKey) for a in ax.artists)    # the scale key
    stars = [line for line in fig.axes[0].get_lines() if line.get_marker() == '*']
    assert len(stars) == 1 and list(stars[0].get_xdata()) == pytest.approx([1450.0])


def test_field_leaves_out_unreachable_grid_poses_and_says_when_there_is_no_model() -> None:
    beyond = Region('far', np.array([1.5, -0.2, -0.3]), np.array([2.5, 0.2, 0.0]))
    panel = plots.field_panel(beyond, GEOMETRY, plots.sample_deflections(
        'far', GEOMETRY, np.empty((0, 4)), np.empty((0, 3)), np.empty(0), None),
        sag, 0.0, {}, points=5)
    assert 0 < len(panel.grid) < 25 and np.all(panel.grid[:, 0] < 2.0)
    predict, note = plots.model_predict('/nonexistent/model.npz')
    assert predict is None and 'no model' in note
    joints, deflections = samples_of('B')
    samples = plots.sample_deflections('B', GEOMETRY, joints, deflections, np.zeros(12), None)
    unmodelled = plots.field_panel(REGIONS['B'], GEOMETRY, samples, None, 0.0, {}, note=note)
    ax = plots.field_figure([unmodelled], 'run').axes[0]
    assert [q.N for q in ax.collections if isinstance(q, Quiver)] == [12]
    assert 'no model' in ax.get_title()


def test_prediction_figure_draws_each_source_against_y_equals_x_with_its_rms() -> None:
    joints, deflections = samples_of('A')
    fitted = plots.sample_deflections('A', GEOMETRY, joints, deflections + 1e-4,
                                      np.zeros(12), sag)     # measured 0.1 mm above
    commanded = forward(GEOMETRY, joints[:3])
    held_out = plots.goal_deflections('A', ['g1', 'g2', 'g3'], commanded,
                                      commanded + sag(joints[:3]), sag(joints[:3]))
    no_model = plots.sample_deflections('B', GEOMETRY, *samples_of('B'), np.zeros(12), None)
    fig = plots.prediction_figure([fitted, held_out, no_model], 'run')
    assert [ax.get_xlabel() for ax in fig.axes] == [
        'measured dx [mm]', 'measured dy [mm]', 'measured dphi [deg]']
    assert [ax.get_ylabel() for ax in fig.axes] == [
        'predicted dx [mm]', 'predicted dy [mm]', 'predicted dphi [deg]']
    for ax in fig.axes:
        lines = ax.get_lines()
        assert [len(line.get_xdata()) for line in lines] == [12, 3, 2]   # y = x last
        assert list(lines[2].get_xdata()) == list(lines[2].get_ydata())
    legend = [t.get_text() for t in fig.axes[0].get_legend().texts]
    assert legend[0] == f'{plots.SAMPLES}, 12: RMS 0.1 mm'
    assert legend[1].startswith(f'{plots.GOALS}, 3: RMS ') and legend[2] == 'y = x'
    assert float(legend[1].split('RMS ')[1].removesuffix(' mm')) < 1e-9   # exact predictions
    assert 'deg' in fig.axes[2].get_legend().texts[0].get_text()


def test_iteration_figure_plots_each_goal_per_move_on_a_log_axis_with_the_tolerance() -> None:
    moves = {'A1': [3e-4, 8e-5, 4e-5], 'B4': [2e-5]}
    fig = plots.iteration_figure(moves, TOLERANCE[0], 'run')
    (ax,) = fig.axes
    assert ax.get_yscale() == 'log' and ax.get_ylabel() == 'measured position error [mm]'
    lines = {line.get_label(): line for line in ax.get_lines()}
    assert list(lines['A1'].get_xdata()) == [1, 2, 3]
    assert list(lines['A1'].get_ydata()) == pytest.approx([0.3, 0.08, 0.04])
    assert list(lines['tolerance 0.05 mm'].get_ydata()) == [0.05, 0.05]
    assert len(ax.get_legend().texts) == 3
    many = plots.iteration_figure({f'g{i}': [1e-4] for i in range(20)}, 5e-5, 'run').axes[0]
    assert len(many.get_lines()) == 21
    assert [t.get_text() for t in many.get_legend().texts] == ['tolerance 0.05 mm']


def test_paper_figure_puts_ours_beside_the_paper_per_target_on_log_axes() -> None:
    goals = [{'target': name, 'mode': mode, 'position_error': error, 'angle_error': 1e-4,
              'succeeded': not (name == 'A2' and mode == 'closed_loop')}
             for name in ('A1', 'A2', 'S1', 'mine')
             for mode, error in (('rigid', 0.02), ('predictive', 1e-4), ('closed_loop', 4e-5))]
    fig = plots.paper_figure(goals, TOLERANCE, 'run')
    position, angle = fig.axes
    assert position.get_yscale() == angle.get_yscale() == 'log'
    assert position.get_ylabel() == 'position error [mm]'
    assert angle.get_ylabel() == '|angle| error [deg]'
    assert [t.get_text() for t in angle.get_xticklabels()] == ['A1', 'A2', 'S1']   # not 'mine'
    bars = {c.get_label(): c for c in position.containers}
    assert list(bars) == ['paper rigid', 'rigid', 'paper learned', 'predictive', 'closed_loop']
    assert [p.get_height() for p in bars['rigid']] == pytest.approx([20.0] * 3)
    assert [p.get_height() for p in bars['paper rigid']] == pytest.approx(
        [13.01, 16.06, 9.93], abs=0.01)
    assert [p.get_hatch() for p in bars['closed_loop']] == [None, 'xx', None]
    assert len(angle.containers[0]) == 3 and len(angle.containers[2]) == 2  # A2: 0.0 deg
    assert '0' in [t.get_text() for t in angle.texts]
    tolerances = [line for line in angle.get_lines() if 'tolerance' in line.get_label()]
    assert list(tolerances[0].get_ydata()) == pytest.approx([0.005, 0.005])
    assert 'tolerance not met' in [t.get_text() for t in fig.legends[0].texts]


def test_write_csv_refuses_a_cell_of_several_values(tmp_path: Path) -> None:
    path = plots.write_csv(tmp_path / 'ok.csv', ('a_mm', 'b'), [{'a_mm': 1.5, 'b': 'x'}])
    assert path.read_text().splitlines() == ['a_mm,b', '1.5,x']
    for bad in ([1.0, 2.0], (1.0, 2.0), np.zeros(2)):
        with pytest.raises(ValueError, match='a_mm'):
            plots.write_csv(tmp_path / 'bad.csv', ('a_mm',), [{'a_mm': bad}])
    assert not (tmp_path / 'bad.csv').exists()


def _trial(name: str, mode: str, target: np.ndarray, moves: list[np.ndarray],
           code: int = 0) -> Trial:
    reached = moves[-1] + np.array([1e-5, 0.0, 0.0])
    x_star = target - sag(inverse(GEOMETRY, target))[0]
    return Trial(
        name=name, group='table10', region=name[0], mode=mode, target=target.tolist(),
        error_code=code, error_string='', reached=reached.tolist(),
        measured=moves[-1].tolist(), position_error=float(np.hypot(*(reached - target)[:2])),
        angle_error=abs(float(reached[2] - target[2])), iterations=len(moves),
        compensation_iterations=2, data_distance=0.5, prediction_std=1e-5, seconds=3.0,
        commanded=x_star.tolist(),
        predicted_deflection=sag(inverse(GEOMETRY, x_star))[0].tolist(),
        moves=[m.tolist() for m in moves])


def _trials() -> list[Trial]:
    trials = []
    for name, target in (('A1', (1.45, -0.15, -45.0)), ('B4', (1.0, -0.5, -100.0))):
        pose = np.array([target[0], target[1], math.radians(target[2])])
        trials += [
            _trial(name, 'rigid', pose, [pose + np.array([0.0, -0.015, -0.02])]),
            _trial(name, 'predictive', pose, [pose + np.array([1e-4, 0.0, 1e-5])]),
            _trial(name, 'closed_loop', pose, [pose + np.array([1e-4, 0.0, 0.0]),
                                               pose + np.array([3e-5, 0.0, 0.0])])]
    return trials


def _one_value_cells(path: Path, fields: tuple[str, ...]) -> list[dict[str, str]]:
    """The rows of a CSV whose header is ``fields`` and whose unit columns hold one number."""
    with path.open() as f:
        reader = csv.DictReader(f)
        rows = list(reader)
        assert tuple(reader.fieldnames) == fields
    for row in rows:
        for name, value in row.items():
            if name.endswith(('_mm', '_deg')) and value != '':
                float(value)
    return rows


def test_trial_csv_rows_are_in_mm_and_deg_one_value_per_cell(tmp_path: Path) -> None:
    trial = _trials()[5]          # B4 closed loop, two moves
    row = trial.csv_row()
    assert set(row) == set(TRIAL_CSV_FIELDS)
    assert row['target_x_mm'] == pytest.approx(1000.0)
    assert row['target_phi_deg'] == pytest.approx(-100.0)
    assert row['measured_position_error_mm'] == pytest.approx(0.03)
    assert row['truth_position_error_mm'] == pytest.approx(0.04)
    assert [r['move'] for r in trial.move_rows()] == [1, 2]
    assert [r['measured_position_error_mm'] for r in trial.move_rows()] == pytest.approx(
        [0.1, 0.03])
    plots.write_csv(tmp_path / 'moves.csv', MOVE_CSV_FIELDS, trial.move_rows())
    assert len(_one_value_cells(tmp_path / 'moves.csv', MOVE_CSV_FIELDS)) == 2


def _learned(tmp_path: Path, name: str) -> tuple[Path, Path]:
    """A dataset file of region ``name``'s samples and a model fitted to them."""
    joints, deflections = samples_of(name)
    dataset = tmp_path / f'{name}.jsonl'
    with DatasetWriter(dataset) as writer:
        for i, (q, d) in enumerate(zip(joints, deflections)):
            rigid = forward(GEOMETRY, q)
            writer.append(Sample(stamp=float(i), joints=tuple(q), payload=0.0,
                                 rigid_pose=tuple(rigid), measured_pose=tuple(rigid + d),
                                 deflection=tuple(d), holes_used=9, residual=1e-5))
    model = tmp_path / f'{name}.model'
    make_predictor('rbf').fit(joints, deflections).save(model)
    return dataset, model


def test_demo_results_hold_every_file_with_one_value_per_csv_cell(tmp_path: Path) -> None:
    trials = _trials()
    learning = {}
    for name in ('A', 'B'):
        dataset, model = _learned(tmp_path, name)
        learning[name] = {'model_path': str(model), 'dataset_path': str(dataset)}
    summary = {'name': 'demo-test', 'world': 'ideal', 'learning': learning,
               'summary': summarise(trials), 'trials': [t.as_dict() for t in trials]}
    out = tmp_path / 'results'
    write_results(summary, trials, out, GEOMETRY, REGIONS)
    assert sorted(p.name for p in out.iterdir()) == [
        'deflection_field.png', 'deflections.csv', 'errors.png', 'iterations.png',
        'moves.csv', 'prediction.png', 'summary.json', 'table.md', 'trials.csv']
    for png in out.glob('*.png'):
        assert png.read_bytes()[:8] == PNG
    rows = _one_value_cells(out / 'trials.csv', TRIAL_CSV_FIELDS)
    assert [r['name'] for r in rows] == [t.name for t in trials]
    assert float(rows[0]['target_y_mm']) == pytest.approx(-150.0)
    moves = _one_value_cells(out / 'moves.csv', MOVE_CSV_FIELDS)
    assert [(r['name'], r['mode'], r['move']) for r in moves if r['name'] == 'A1'] == [
        ('A1', 'rigid', '1'), ('A1', 'predictive', '1'), ('A1', 'closed_loop', '1'),
        ('A1', 'closed_loop', '2')]
    deflections = _one_value_cells(out / 'deflections.csv', plots.DEFLECTION_CSV_FIELDS)
    sources = [(r['region'], r['source']) for r in deflections]
    assert sources.count(('A', plots.SAMPLES)) == 12 and sources.count(('B', plots.GOALS)) == 1
    assert all(r['predicted_dx_mm'] != '' for r in deflections)
    assert json.loads((out / 'summary.json').read_text())['name'] == 'demo-test'


def _stamp(seconds: float) -> Time:
    return Time(sec=int(seconds), nanosec=int(round(seconds % 1 * 1e9)))


def _xyphi(pose: np.ndarray) -> PlanarPose:
    return PlanarPose(x=float(pose[0]), y=float(pose[1]), phi=float(pose[2]))


def test_bag_export_draws_the_samples_with_their_model_and_the_paper_targets(
        tmp_path: Path) -> None:
    bag = tmp_path / 'run'
    with BagWriter(bag) as writer:
        for topic, kind in ((topics.absolute(topics.SAMPLES), 'DeflectionSample'),
                            (topics.absolute(topics.MODEL), 'ModelInfo'),
                            (topics.absolute(topics.OUTCOMES), 'GoalOutcome'),
                            (topics.absolute(topics.TIP_POSE_TRUTH), 'TipPose')):
            writer.add_topic(topic, f'flexarm_msgs/msg/{kind}')
        for name in ('A', 'B'):
            _, model = _learned(tmp_path, name)
            for q, d in zip(*samples_of(name)):
                rigid = forward(GEOMETRY, q)
                writer.write(topics.absolute(topics.SAMPLES), serialize_message(DeflectionSample(
                    joint_positions=q.tolist(), rigid_pose=_xyphi(rigid),
                    measured_pose=_xyphi(rigid + d), deflection=_xyphi(d))), 0)
            writer.write(topics.absolute(topics.MODEL), serialize_message(ModelInfo(
                version=name, kind='rbf', path=str(model), dataset=name)), 0)
        for i, trial in enumerate(_trials()):
            truth = TipPose(pose=_xyphi(np.array(trial.reached)), valid=True)
            truth.header.stamp = _stamp(i + 0.5)
            writer.write(topics.absolute(topics.TIP_POSE_TRUTH), serialize_message(truth), 0)
            writer.write(topics.absolute(topics.OUTCOMES), serialize_message(GoalOutcome(
                stamp=_stamp(i + 0.9), trial=f'run/{trial.name}/{trial.mode}',
                mode=('rigid', 'predictive', 'closed_loop').index(trial.mode),
                target=_xyphi(np.array(trial.target)), measured=True,
                measured_pose=_xyphi(np.array(trial.measured)),
                commanded_pose=_xyphi(np.array(trial.commanded)),
                predicted_deflection=_xyphi(np.array(trial.predicted_deflection)),
                iterations=trial.iterations)), 0)
    written = export_figures(bag, tmp_path / 'out')
    assert sorted(p.name for p in written) == [
        'run_deflection_field.png', 'run_deflections.csv', 'run_errors.png',
        'run_prediction.png']
    rows = _one_value_cells(tmp_path / 'out' / 'run_deflections.csv',
                            plots.DEFLECTION_CSV_FIELDS)
    assert [(r['region'], r['source']) for r in rows].count(('A', plots.SAMPLES)) == 12
    assert [r['label'] for r in rows if r['source'] == plots.GOALS] == [
        'run/A1/predictive', 'run/B4/predictive']
    assert all(r['predicted_dx_mm'] != '' for r in rows)
    for path in written:
        if path.suffix == '.png':
            assert path.read_bytes()[:8] == PNG
