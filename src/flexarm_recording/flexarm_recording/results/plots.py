"""Figures of a run for a remote-handling engineer, and the CSV tables behind them (pure: plain
data in, a matplotlib Figure or a file out; no ROS).

* :func:`field_figure`: where the arm sags — the measured deflection at the learning samples
  and the model's predicted field on a grid over each working region, arrows scaled with a
  scale key, the region's box and the goal targets marked (``deflection_field.png``).
* :func:`prediction_figure`: predicted against measured deflection (dx, dy mm, dφ deg) with
  the y = x line and each series' RMS error in the legend (``prediction.png``).
* :func:`iteration_figure`: the measured position error after every move of each
  CLOSED_LOOP goal, log scale, with the tolerance line (``iterations.png``).
* :func:`paper_figure`: position and angle error per target and mode beside the paper's
  Tables 9-10, log scale, with the tolerance line (``errors.png``).

Inputs are in SI units (m, rad) like everything in the graph; the figures and
:data:`DEFLECTION_CSV_FIELDS` rows show mm and degrees, the unit in every axis label and
column name. :func:`write_csv` refuses a cell that is not one value.

Decisions: the predicted field is drawn at the middle tip angle of each region's box (a planar
plot cannot show the third dimension; the title says which angle), at the rigid tip pose of
the joints the grid pose asks for, each arrow the deflection there. The samples' arrows start
at their rigid pose too, so both fields read alike. The learning samples' predictions are
in-sample (the model was fitted to them) and are labelled so; PREDICTIVE goals are held out:
their measured deflection is the measured minus the commanded pose (x*, whose rigid inverse the
arm was sent to). CLOSED_LOOP goals do not count there: their corrected x* keeps the first
prediction. Figures are built with matplotlib's object API (``Figure``, no pyplot: no global
state, nothing to close) and rendered by its Agg canvas.
"""
from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch, Rectangle
from matplotlib.ticker import FormatStrFormatter, MaxNLocator, NullFormatter

from flexarm_bringup.launcher import node_name
from flexarm_control.execution.modes import MODE_LABELS
from flexarm_deflection.deflection_field import deflection_field
from flexarm_deflection.models import load_model
from flexarm_core.atomic_file import atomic_write
from flexarm_core.kinematics import ArmGeometry, forward, wrap_angle
from flexarm_core.paper import TABLE_9, TABLE_10
from flexarm_core.params import load_config
from flexarm_core.regions import Region

# predict(joints (N, 4), payload (N,) [kg]) -> deflections (N, 3) [m, m, rad]
Predict = Callable[[np.ndarray, np.ndarray], np.ndarray]
# at most this many targets are named, and closed-loop goals listed in the legend
NAMED_AT_MOST = 12
DEFLECTION_CSV_FIELDS = (
    'region', 'source', 'label', 'rigid_x_mm', 'rigid_y_mm', 'rigid_phi_deg',
    'measured_dx_mm', 'measured_dy_mm', 'measured_dphi_deg',
    'predicted_dx_mm', 'predicted_dy_mm', 'predicted_dphi_deg')
SAMPLES = 'learning samples (fitted)'
GOALS = 'PREDICTIVE goals (held out)'


def mm_deg(values: np.ndarray) -> np.ndarray:
    """(..., 3) [m, m, rad] -> [mm, mm, deg]."""
    return np.asarray(values, dtype=float) * np.array([1e3, 1e3, 180.0 / math.pi])


@dataclass(frozen=True)
class Deflections:
    """Deflections at arm poses: learning samples or goals of one region (SI units)."""

    region: str
    source: str                     # SAMPLES or GOALS
    labels: list[str]               # sample number or trial name, per row
    rigid: np.ndarray               # (N, 3) rigid tip pose of the joints [m, m, rad]
    measured: np.ndarray            # (N, 3) measured minus rigid pose
    predicted: np.ndarray | None    # (N, 3) the model's prediction (None: no model at hand)


@dataclass(frozen=True)
class FieldPanel:
    """One region of :func:`field_figure`."""

    region: Region
    samples: Deflections
    grid: np.ndarray                # (G, 3) rigid tip poses of the grid [m, m, rad]
    grid_deflection: np.ndarray     # (G, 3) predicted deflection there
    targets: Mapping[str, np.ndarray]   # name -> (3,) target pose
    note: str = ''                  # e.g. why there is no predicted field


def model_predict(path: str | Path) -> tuple[Predict | None, str]:
    """The model file's prediction, or None and why not (missing, unreadable)."""
    try:
        model = load_model(path)
    except (OSError, ValueError) as exc:
        return None, f'no model ({type(exc).__name__}: {path})'

    def predict(joints: np.ndarray, payload: np.ndarray) -> np.ndarray:
        return model.predict(joints, payload if model.settings['payload_input'] else None)
    return predict, ''


def sample_deflections(region: str, geometry: ArmGeometry, joints: np.ndarray,
                       deflections: np.ndarray, payload: np.ndarray,
                       predict: Predict | None) -> Deflections:
    """Learning samples (joints (N, 4), measured deflections (N, 3), payload (N,) [kg])."""
    joints = np.asarray(joints, dtype=float).reshape(-1, 4)
    return Deflections(
        region, SAMPLES, [str(i) for i in range(len(joints))], forward(geometry, joints),
        np.asarray(deflections, dtype=float).reshape(-1, 3),
        None if predict is None or not len(joints) else predict(joints, np.asarray(payload)))


def goal_deflections(region: str, labels: Sequence[str], commanded: np.ndarray,
                     measured: np.ndarray, predicted: np.ndarray) -> Deflections:
    """PREDICTIVE goals: commanded pose x*, measured pose and predicted deflection (N, 3)."""
    commanded = np.asarray(commanded, dtype=float).reshape(-1, 3)
    difference = np.asarray(measured, dtype=float).reshape(-1, 3) - commanded
    difference[:, 2] = wrap_angle(difference[:, 2])
    return Deflections(region, GOALS, list(labels), commanded, difference,
                       np.asarray(predicted, dtype=float).reshape(-1, 3))


def field_panel(region: Region, geometry: ArmGeometry, samples: Deflections,
                predict: Predict | None, payload: float,
                targets: Mapping[str, np.ndarray], points: int = 9, note: str = '',
                ) -> FieldPanel:
    """The predicted field on ``points`` x ``points`` poses over the region's box at its middle
    tip angle (:func:`~flexarm_deflection.deflection_field.deflection_field`), at
    ``payload``."""
    if predict is None:
        return FieldPanel(region, samples, np.empty((0, 3)), np.empty((0, 3)), targets, note)
    grid, predicted = deflection_field(
        geometry, region, lambda joints: predict(joints, np.full(len(joints), float(payload))),
        points)
    return FieldPanel(region, samples, grid, predicted, targets, note)


def _key_length(largest: float) -> float:
    """A round arrow length (1, 2 or 5 x 10^k) not above ``largest`` > 0."""
    power = 10.0 ** math.floor(math.log10(largest))
    return max(step * power for step in (1, 2, 5) if step * power <= largest)


def _field_axes(ax: Axes, panel: FieldPanel) -> None:
    box_lower, box_upper = panel.region.lower * 1e3, panel.region.upper * 1e3
    grid, grid_d = panel.grid[:, :2] * 1e3, panel.grid_deflection[:, :2] * 1e3
    base, measured = panel.samples.rigid[:, :2] * 1e3, panel.samples.measured[:, :2] * 1e3
    ax.add_patch(Rectangle(box_lower[:2], *(box_upper - box_lower)[:2], fill=False,
                           linestyle='--', edgecolor='grey', label=f'region {panel.region.name}'))
    spacing = (box_upper - box_lower)[:2].min() / 8
    lengths = np.hypot(*np.vstack([grid_d, measured]).T)
    largest = float(lengths.max()) if lengths.size and lengths.max() > 0 else 1.0
    scale = 0.9 * spacing / largest             # plot mm per mm of deflection
    arrows = {'angles': 'xy', 'scale_units': 'xy', 'scale': 1.0 / scale, 'width': 0.004}
    quiver = None
    if len(grid):
        quiver = ax.quiver(*grid.T, *grid_d.T, color='tab:blue', alpha=0.6, **arrows,
                           label=f'predicted (grid at phi = {math.degrees(panel.grid[0, 2]):.0f}'
                                 ' deg)')
    if len(base):
        ax.plot(*base.T, '.', color='black', markersize=3)
        quiver = ax.quiver(*base.T, *measured.T, color='black', **arrows,
                           label=f'measured at {len(base)} learning samples')
    if quiver is not None:
        key = _key_length(largest)
        ax.quiverkey(quiver, 0.82, 1.02, key, f'{key:g} mm', labelpos='E',
                     coordinates='axes', color='black')
    if panel.targets:
        xy = np.array([pose[:2] for pose in panel.targets.values()]) * 1e3
        ax.plot(*xy.T, '*', color='tab:red', markersize=11, linestyle='none',
                label=f'targets ({len(xy)})')
        if len(xy) <= NAMED_AT_MOST:
            for name, (x, y) in zip(panel.targets, xy):
                ax.annotate(name, (x, y), xytext=(4, 4), textcoords='offset points',
                            fontsize='small', color='tab:red')
    ax.set_aspect('equal', adjustable='datalim')
    ax.set_xlabel('x [mm]')
    ax.set_ylabel('y (up) [mm]')
    ax.set_title(f'region {panel.region.name}: arrows x{scale:.1f}, key:'
                 + (f'\n{panel.note}' if panel.note else ''), fontsize='medium')
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize='small', loc='upper center', bbox_to_anchor=(0.5, -0.1), ncols=2)


def field_figure(panels: Sequence[FieldPanel], title: str) -> Figure:
    """One panel per region: measured (samples) and predicted (grid) deflection arrows in the
    arm's plane, mm, each panel with its scale key."""
    fig = Figure(figsize=(5.5 * len(panels), 6.5), layout='constrained')
    for ax, panel in zip(fig.subplots(1, len(panels), squeeze=False)[0], panels):
        _field_axes(ax, panel)
    fig.suptitle(f'{title}: tip deflection (measured minus rigid pose)')
    return fig


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def prediction_figure(sets: Sequence[Deflections], title: str) -> Figure:
    """Predicted against measured dx, dy [mm] and dphi [deg], one series per source (sets
    without a prediction left out), RMS of predicted minus measured in the legend."""
    fig = Figure(figsize=(14, 4.8), layout='constrained')
    axes = fig.subplots(1, 3)
    by_source: dict[str, list[Deflections]] = {}
    for s in sets:
        if s.predicted is not None and len(s.labels):
            by_source.setdefault(s.source, []).append(s)
    drawn: list[np.ndarray] = []
    for source, chosen in by_source.items():
        measured = mm_deg(np.vstack([s.measured for s in chosen]))
        predicted = mm_deg(np.vstack([s.predicted for s in chosen]))
        drawn += [measured, predicted]
        for i, (ax, unit) in enumerate(zip(axes, ('mm', 'mm', 'deg'))):
            ax.plot(measured[:, i], predicted[:, i], 'o', markersize=4, alpha=0.7,
                    label=f'{source}, {len(measured)}: RMS '
                          f'{_rms(predicted[:, i] - measured[:, i]):.3g} {unit}')
    values = np.vstack(drawn) if drawn else np.zeros((1, 3))
    for i, (ax, name, unit) in enumerate(zip(axes, ('dx', 'dy', 'dphi'), ('mm', 'mm', 'deg'))):
        low, high = values[:, i].min(), values[:, i].max()
        ax.plot([low, high], [low, high], color='grey', linewidth=1, label='y = x')
        ax.set_xlabel(f'measured {name} [{unit}]')
        ax.set_ylabel(f'predicted {name} [{unit}]')
        ax.set_aspect('equal', adjustable='datalim')
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize='x-small', loc='upper left')
    fig.suptitle(f'{title}: predicted against measured deflection')
    return fig


def _log_axis(ax: Axes) -> None:
    ax.set_yscale('log')
    ax.yaxis.set_major_formatter(FormatStrFormatter('%g'))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.grid(True, which='both', axis='y', alpha=0.3)


def iteration_figure(moves: Mapping[str, Sequence[float]], tolerance: float,
                     title: str) -> Figure:
    """Measured position error [m in, mm shown] after each move of every CLOSED_LOOP goal
    (``moves``: goal name -> errors in move order), with the ``tolerance`` [m] line."""
    fig = Figure(figsize=(8, 5), layout='constrained')
    ax = fig.subplots()
    for name, errors in moves.items():
        values = np.asarray(errors, dtype=float) * 1e3
        ax.plot(np.arange(1, len(values) + 1), np.where(values > 0, values, np.nan), 'o-',
                markersize=4, alpha=0.8, label=name)
    ax.axhline(tolerance * 1e3, color='tab:red', linestyle='--',
               label=f'tolerance {tolerance * 1e3:g} mm')
    _log_axis(ax)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel('move (1 = the predictive move, then corrections)')
    ax.set_ylabel('measured position error [mm]')
    handles, labels = ax.get_legend_handles_labels()
    if len(moves) > NAMED_AT_MOST:       # the tolerance only: too many goals to name
        handles, labels = handles[-1:], labels[-1:]
    ax.legend(handles, labels, fontsize='x-small', ncols=2)
    ax.set_title(f'{title}: CLOSED_LOOP goals, {len(moves)}')
    return fig


def paper_errors() -> dict[str, dict[str, tuple[float, float | None] | None]]:
    """The paper's (position mm, |angle| deg) per target: 'paper rigid' and 'paper learned'
    (Table 10's neural network, Table 9's 40 samples)."""
    errors = {t.name: {'paper rigid': t.rigid_errors, 'paper learned': t.compensated_errors}
              for t in TABLE_10}
    errors.update({name: {'paper rigid': rigid, 'paper learned': learned}
                   for name, _, rigid, learned in TABLE_9})
    return errors


def paper_figure(goals: Sequence[Mapping[str, Any]], tolerance: tuple[float, float],
                 title: str) -> Figure:
    """Position [mm] and |angle| [deg] error bars per target of the paper's tables, ours per
    mode beside the paper's, with the CLOSED_LOOP ``tolerance`` (m, rad) lines.

    ``goals``: dicts with ``target`` (name), ``mode``, ``position_error`` [m],
    ``angle_error`` [rad] and ``succeeded`` of the goals whose reached pose is an accuracy
    (succeeded, or tolerance not met: its bar is hatched); targets the paper does not have
    are left out. An error printed 0 (the paper's 0.0 deg) is written '0': no bar on a log
    axis.
    """
    paper = paper_errors()
    ours = {(g['target'], g['mode']): g for g in goals if g['target'] in paper}
    names = [name for name in paper if any(n == name for n, _ in ours)]
    bars = ('paper rigid', 'rigid', 'paper learned', 'predictive', 'closed_loop')
    colours = {'paper rigid': '#f4b183', 'rigid': 'tab:orange', 'paper learned': '#9dc3e6',
               'predictive': 'tab:blue', 'closed_loop': 'tab:green'}
    width = 0.8 / len(bars)
    fig = Figure(figsize=(max(8.0, 1.3 * len(names) + 3), 7), layout='constrained')
    axes = fig.subplots(2, 1, sharex=True)
    failed = False
    for row, (ax, unit, scale) in enumerate(zip(axes, ('mm', 'deg'),
                                                (1e3, 180.0 / math.pi))):
        for b, bar in enumerate(bars):
            xs, heights, hatches, zeros = [], [], [], []
            for j, name in enumerate(names):
                if bar in MODE_LABELS:
                    goal = ours.get((name, bar))
                    value = None if goal is None else abs(
                        goal['position_error' if row == 0 else 'angle_error']) * scale
                    hatch = '' if goal is None or goal['succeeded'] else 'xx'
                else:
                    errors = paper[name][bar]
                    value, hatch = None if errors is None else errors[row], ''
                if value is None:
                    continue
                x = j + (b - (len(bars) - 1) / 2) * width
                if value > 0:
                    xs.append(x)
                    heights.append(value)
                    hatches.append(hatch)
                else:
                    zeros.append(x)
            failed = failed or any(hatches)
            drawn = ax.bar(xs, heights, width, color=colours[bar], label=bar)
            for patch, hatch in zip(drawn, hatches):
                if hatch:
                    patch.set_hatch(hatch)
                    patch.set_edgecolor('tab:red')
            for x in zeros:
                ax.text(x, 0.02, '0', transform=ax.get_xaxis_transform(), ha='center',
                        fontsize='small')
        ax.axhline(tolerance[row] * scale, color='tab:red', linestyle='--',
                   label=f'CLOSED_LOOP tolerance {tolerance[row] * scale:g} {unit}')
        _log_axis(ax)
        ax.set_ylabel(f'{"position" if row == 0 else "|angle|"} error [{unit}]')
    axes[1].set_xticks(range(len(names)), names)
    axes[1].set_xlabel('target (Table 10: A1-B6, Table 9: S1-S5); "0": an error printed 0.0')
    handles, labels = axes[0].get_legend_handles_labels()
    if failed:
        handles.append(Patch(facecolor='white', edgecolor='tab:red', hatch='xx'))
        labels.append('tolerance not met')
    fig.legend(handles, labels, loc='outside lower center', fontsize='small', ncols=4)
    fig.suptitle(f'{title}: error per target and mode, ours beside the paper\'s')
    return fig


def closed_loop_tolerance() -> tuple[float, float]:
    """The compensator's default CLOSED_LOOP tolerance (position [m], angle [rad]) from its
    config/compensator.yaml."""
    config = load_config('compensator.yaml', node_name=node_name('compensator'))
    return float(config['position_tolerance']), float(config['angle_tolerance'])


def save_figure(fig: Figure, path: Path) -> Path:
    """Write ``fig`` as a PNG to ``path`` atomically; returns ``path``."""
    atomic_write(path, lambda f: fig.savefig(f, dpi=100, format='png'))
    return path


def deflection_rows(sets: Sequence[Deflections]) -> list[dict[str, Any]]:
    """Rows of :data:`DEFLECTION_CSV_FIELDS` (mm, deg; predicted cells empty without a model)."""
    rows = []
    for s in sets:
        rigid, measured = mm_deg(s.rigid), mm_deg(s.measured)
        predicted = None if s.predicted is None else mm_deg(s.predicted)
        for i, label in enumerate(s.labels):
            row = {'region': s.region, 'source': s.source, 'label': label,
                   **dict(zip(DEFLECTION_CSV_FIELDS[3:6], rigid[i].tolist())),
                   **dict(zip(DEFLECTION_CSV_FIELDS[6:9], measured[i].tolist()))}
            if predicted is not None:
                row.update(zip(DEFLECTION_CSV_FIELDS[9:], predicted[i].tolist()))
            rows.append(row)
    return rows


def write_csv(path: Path, fields: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> Path:
    """Write ``rows`` under the header ``fields`` atomically; ValueError for a cell that holds
    more than one value (a list, tuple, dict or array). Returns ``path``."""
    for row in rows:
        for name, value in row.items():
            if isinstance(value, (list, tuple, dict, set, np.ndarray)):
                raise ValueError(f'{path.name}: column {name} holds {value!r}, not one value')
    text = io.StringIO(newline='')
    writer = csv.DictWriter(text, fieldnames=list(fields))
    writer.writeheader()
    writer.writerows(rows)
    atomic_write(path, lambda f: f.write(text.getvalue().encode()))
    return path
