"""What ``flexarm status`` and ``flexarm up`` say of a graph, for humans (mm and deg): the
lines made from the plain data :mod:`flexarm_bringup.graph_status` reads, and the
``/diagnostics`` status (:class:`Heard`) they are made from. No rclpy."""
from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from flexarm_bringup.launcher import node_name
from flexarm_core.health_report import ERROR


@dataclass(frozen=True)
class Heard:
    """A status of ``/diagnostics`` as last heard."""

    level: int
    message: str
    values: Mapping[str, str] = field(default_factory=dict)


def real_time_factor(report: Heard | None) -> dict[str, float] | None:
    """The simulator's achieved and set real-time factors from its ``controller`` report
    (None: no simulator, or not heard)."""
    try:
        return {'achieved': float(report.values['real-time factor']),
                'set': float(report.values['real-time factor set'])}
    except (AttributeError, KeyError, ValueError):
        return None


def clock_text(report: Heard | None) -> str | None:
    """The simulator's part in the domain's ``/clock`` and its time, from its ``controller``
    report (None: no simulator, or not heard)."""
    if report is None or 'clock' not in report.values:
        return None
    return (f'the simulator {report.values["clock"]}, at sim time '
            f'{report.values.get("sim time [s]", "?")} s')


def calibration_text(heard: Heard | None) -> str:
    """Whether the arm's camera is calibrated, from the vision node's report: when, against
    what; or NOT calibrated; or why the file is unusable (its ERROR)."""
    if heard is None:
        return 'camera calibration: not heard (no vision node)'
    return f'camera calibration: {"PROBLEM: " if heard.level == ERROR else ""}{heard.message}'


def health_line(health: dict[str, Any] | None, compensator: bool, model: bool) -> str:
    """The model health line; without a health message, why (``compensator``: the node runs,
    ``model``: it runs a model, whose health it publishes)."""
    if health is None:
        return ('model health: none (no model in use)' if compensator and not model else
                'model health: not heard' if compensator else
                'model health: none (no compensator)')
    if not health['regions']:
        return 'model health: no measured goal yet'
    regions = ', '.join(f'{r["name"]} {r["median_position_residual"] * 1e3:.3f} mm '
                        f'({r["observations"]} measurements{", STALE" if r["stale"] else ""})'
                        for r in health['regions'])
    line = (f'model health (median residual; stale above '
            f'{health["stale_residual"] * 1e3:.3f} mm): {regions}; '
            f'{health["bound_misses"]} of {health["bound_goals"]} measured goals beyond their '
            f'stated bound, plans state {health["bound_factor"]:.1f} x (position) and '
            f'{health["angle_bound_factor"]:.1f} x (angle) the calibrated one')
    label = 'WARNING' if health['stale'] else 'note'
    return line + (f'\n  {label}: {health["summary"]}' if health['summary'] else '')


def model_line(label: str, model: dict[str, Any] | None) -> str:
    if model is None:
        return f'{label}: none'
    age = '' if model['age_s'] is None else f', trained {_duration(model["age_s"])} ago'
    err = model['max_error']
    payloads = ', '.join(f'{p:g}' for p in model['payloads']) or '?'
    line = (f'{label}: v{model["version"]} {model["kind"]}, dataset '
            f'{model["dataset"] or "?"}, {model["samples"]} samples at {payloads} kg{age}; '
            f'{model["validation"] or "validation"} max |error| {err[0] * 1e3:.3f} mm, '
            f'{err[1] * 1e3:.3f} mm, {math.degrees(err[2]):.4f} deg')
    refresh = model.get('refresh')
    if refresh:
        line += (f'\n  refresh of v{refresh["of"]}: {refresh["samples"]} samples '
                 f'({refresh["dataset"] or "?"}), median residual '
                 f'{refresh["residual_before"] * 1e3:.3f} mm before, '
                 f'{refresh["residual_after"] * 1e3:.3f} mm after')
    return line + (f'\n  WARNING: {model["warning"]}' if model['warning'] else '')


def _duration(seconds: float) -> str:
    for unit, size in (('d', 86400), ('h', 3600), ('min', 60)):
        if seconds >= size:
            return f'{seconds / size:.1f} {unit}'
    return f'{seconds:.0f} s'


def other_arms_text(arms: Iterable[str]) -> str:
    """Where the arms of the domain are, for a status that found none in its namespace
    ('' if there are none)."""
    arms = sorted(arms)
    if not arms:
        return ''
    names = ', '.join(arm or '(no namespace)' for arm in arms)
    return (f'none in this namespace; the domain runs {len(arms)} arm(s) elsewhere: {names} '
            '(pass --namespace NS)')


def status_text(status: dict[str, Any], record: dict[str, Any] | None) -> str:
    """``flexarm status`` for humans."""
    lines = [f'ROS_DOMAIN_ID={status["domain_id"]}']
    if record is None:
        lines.append('supervisor: none found (not started by `flexarm up` on this machine)')
    else:
        lines.append(f'supervisor: pid {record["supervisor_pid"]}, robot {record["robot"]}, '
                     f'logs in {record["run_dir"]}')
        if record.get('remote'):
            lines.append(f'part of the graph: {", ".join(record["nodes"])} here; '
                         f'{", ".join(record["remote"])} on other hosts')
    restarts = {} if record is None else {n: v['restarts'] for n, v in record['nodes'].items()}
    up = [n + (f' (restarted {restarts[n]}x)' if restarts.get(n) else '')
          for n, alive in status['nodes'].items() if alive]
    lines.append('nodes up: ' + (', '.join(up) or other_arms_text(status.get('arms', []))
                                 or 'none: no flexarm graph in this domain (start one with '
                                 '`flexarm up`)'))
    if status['controller'] is None:
        lines.append('controller: none')
    else:
        rate = status['joint_state_rate_hz']
        link = f'joint states at {rate:.0f} Hz' if rate else 'NO joint states for 1 s'
        factor = status.get('real_time_factor')
        if factor:
            link += f', x{factor["achieved"]:.2f} real time (set x{factor["set"]:g})'
        lines.append(f'controller: {status["controller"]}, {link}')
        if status.get('clock'):
            lines.append(f'clock: {status["clock"]}')
    lines.append(model_line('model driving the arm (compensator)', status['active_model']))
    learner, active = status['learner_model'], status['active_model']
    if learner is not None and (active is None or learner['version'] != active['version']):
        lines.append(model_line('model announced by the learner (NOT in use)', learner))
    lines.append(health_line(status.get('model_health'),
                              bool(status['nodes'].get(node_name('compensator'))),
                              status['active_model'] is not None))
    payload = status['payload_kg']
    known = [f'{what} {value:g} kg' for what, value in payload.items() if value is not None]
    lines.append('payload: ' + (', '.join(known) or 'unknown'))
    if 'camera_calibration' in status:
        lines.append(status['camera_calibration'])
    lines.append(f'recording: bags/{status["bag"]}' if status['bag'] else 'recording: no')
    problems = status.get('problems') or []
    lines.append('PROBLEMS:' + ''.join(f'\n  {p}' for p in problems) if problems
                 else 'problems: none')
    return '\n'.join(lines)


def starting_model_text(active: dict[str, Any] | None, learner: Heard | None) -> str | None:
    """``flexarm up``'s line on the model the graph starts with: the compensator's ``active``
    model; without one, the learner's ``model`` status (an ERROR says why there is none, e.g.
    a damaged model record); None while it is too early to tell (the learner announced a model
    the compensator has not loaded yet, or has not reported)."""
    if active is not None:
        return model_line('model driving the arm', active)
    if learner is None or (learner.level != ERROR and learner.values.get('version')):
        return None
    if learner.level == ERROR:
        return 'model driving the arm: none: the learner could not announce one (PROBLEM below)'
    return ('model driving the arm: none yet (PREDICTIVE goals are refused until `flexarm '
            'train`; CLOSED_LOOP starts from the rigid plan)')
