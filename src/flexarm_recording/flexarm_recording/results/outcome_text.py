"""Outcomes in words for the command line: exit codes, result codes by name with a hint of
what to do, and poses and SI figures in the operator's units (mm, deg). Pure (no ROS calls):
result types are passed in, so every action's codes come from its own Result constants.
"""
from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from enum import IntEnum


class Exit(IntEnum):
    """Exit status of ``flexarm``, one per kind of outcome (meanings: EXIT_MEANINGS)."""

    OK = 0
    FAILED = 1
    USAGE = 2
    NO_GRAPH = 3
    BUSY = 4
    DEGRADED = 5
    NOTHING_TO_CANCEL = 6
    INTERRUPTED = 130


EXIT_MEANINGS = {
    Exit.OK: 'success',
    Exit.FAILED: 'the server refused the goal or it failed (result code by name, and a hint)',
    Exit.USAGE: 'usage error: bad arguments, refused before connecting',
    Exit.NO_GRAPH: 'no graph answered within --wait, a server was lost mid-goal, or the goal '
                   'outlasted --timeout (it was cancelled)',
    Exit.BUSY: 'busy: another motion holds the arm (a goal, collection, refresh or '
               'calibration, named); try again when it has ended (or end it with flexarm cancel)',
    Exit.DEGRADED: 'status: a node of the graph is down, or one reports an ERROR (e.g. a '
                   'damaged calibration file or model record: named, with the reason)',
    Exit.NOTHING_TO_CANCEL: 'cancel: no goal was running and no motion held the arm, nothing '
                            'was cancelled',
    Exit.INTERRUPTED: 'interrupted (Ctrl-C or SIGTERM): a running goal was cancelled',
}

ARM_BUSY_HINT = ('wait until the motion named has ended, or end it with `flexarm cancel`, then '
                 'try again')
MOVE_HINTS = {
    'INVALID_GOAL': 'give finite numbers, phi within -180..180 deg, tolerances 0 (the '
                    'default) or within the bounds the reason names, and at most as many '
                    'corrections as it names',
    'UNREACHABLE': 'choose a target the arm can reach (the regions of config/learner.yaml '
                   'are inside its reach); --mode rigid tells whether the rigid arm reaches it',
    'NO_MODEL': 'train a model first (flexarm collect 40 --region A --dataset A; flexarm train '
                '--dataset A), or use --mode rigid or closed_loop',
    'MEASUREMENT_FAILED': 'the camera gave no valid settled tip pose: check the vision node '
                          '(its log in runs/<name>/)',
    'TOLERANCE_NOT_MET': 'loosen --position-tolerance/--angle-tolerance, allow more '
                         '--max-corrections (CLOSED_LOOP), or retrain the model',
    'CONTROLLER_TIMEOUT': 'the joints did not follow the command, or the controller refused '
                          'or aborted it (the reason gives its words): check the controller '
                          '(`flexarm status` names a node that died) and /joint_states',
    'CANCELED': 'the goal was cancelled (flexarm cancel, another client, or the server: the '
                'reason says why); the arm stopped where it was',
    'OUTSIDE_LEARNED_DATA': 'collect samples around this target and train again, or pass '
                            '--allow-extrapolation to run it with a warning',
    'ARM_BUSY': ARM_BUSY_HINT,
    'BOUND_EXCEEDS_TOLERANCE': 'use --mode auto or closed_loop (they measure and correct), '
                               'collect samples where the reason says, or pass '
                               '--allow-extrapolation to move anyway',
}
COLLECT_HINTS = {
    'INVALID_GOAL': 'check the count, --region, --strategy and --dataset (flexarm collect -h)',
    'CANCELED': 'another client cancelled it; the samples collected before are kept',
    'FAILED': "see the learner's log in runs/<name>/ (the samples collected before are kept)",
    'ARM_BUSY': ARM_BUSY_HINT,
}
TRAIN_HINT = ('do what the reason asks (e.g. collect more samples, other --settings); the '
              'previous model stays active')

_BUSY = re.compile(r'(?:^|: )busy:')
_SI_VALUE = re.compile(r'(?<![\w.])(-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?) (m|rad)\b(?!/)')


def code_names(result_type: type) -> dict[int, str]:
    """Result code -> constant name of an action's Result class (e.g. -2 -> 'UNREACHABLE')."""
    return {value: name for name, value in vars(result_type).items()
            if name.isupper() and isinstance(value, int) and not isinstance(value, bool)}


def code_name(result_type: type, code: int) -> str:
    """The constant naming ``code`` in ``result_type``, or the bare number if none does."""
    return code_names(result_type).get(code, str(code))


def human_units(text: str) -> str:
    """``text`` with every SI figure ('0.005 m', '1.2 rad') in mm and deg."""
    def convert(match: re.Match[str]) -> str:
        value = float(match.group(1))
        if match.group(2) == 'm':
            return f'{value * 1e3:.6g} mm'
        return f'{math.degrees(value):.6g} deg'
    return _SI_VALUE.sub(convert, text)


def pose_text(pose: Sequence[float]) -> str:
    """A pose (x, y, phi) [m, m, rad] as 'x=… mm, y=… mm, phi=… deg'."""
    x, y, phi = (float(v) for v in pose)
    return f'x={x * 1e3:.2f} mm, y={y * 1e3:.2f} mm, phi={math.degrees(phi):.3f} deg'


def is_busy(reason: str) -> bool:
    """Whether a server's reason says it was busy with another goal or collection ('busy: …',
    also after a prefix such as 'training failed: ')."""
    return _BUSY.search(reason) is not None


def busy_text(server: str) -> str:
    """What a busy server means for the operator."""
    return (f'busy: another goal is running on {server} (one at a time); wait until it has '
            'ended, or end it with `flexarm cancel`, then try again')


def arm_busy_text(reason: str) -> str:
    """A goal refused because another motion holds the arm: the server names that motion."""
    return (f'refused (ARM_BUSY; nothing moved): {reason or "another motion holds the arm"}'
            f'\n  what to do: {ARM_BUSY_HINT}')


def failure_text(name: str, reason: str, hints: Mapping[str, str], moved: bool) -> str:
    """'refused (NAME; nothing moved): reason', or 'failed (NAME): reason' once the arm has
    moved, and a hint of what to do; SI figures of the reason in mm and deg."""
    status = f'failed ({name})' if moved else f'refused ({name}; nothing moved)'
    hint = hints.get(name)
    return f'{status}: {human_units(reason) or "no reason given"}' + (
        f'\n  what to do: {hint}' if hint else '')
