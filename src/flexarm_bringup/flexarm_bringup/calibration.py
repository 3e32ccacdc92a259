"""The tool calibration of a running graph (``flexarm calibrate``, and the first step of
``flexarm demo`` / ``benchmark`` in the realistic world).

The arm moves RIGID to the six Table 10 poses; at each one the vision node's measured pose
(averaged, settled) is paired with the mean of 3 poses of the reference instrument (a
``flexarm_msgs/TipPose`` topic: a laser tracker at the tool point on a real site, the
simulator's ground truth here), :func:`~flexarm_control.tool_calibration.
calibrate_against_reference` fits the camera's error in the tool frame, and the correction is
stored atomically and set on the running vision node (``tool_correction``), which reports
every pose through it from then on. Its goals are named ``calibration/<target>/rigid``, so a
bag tells them from the operator's goals. The measurements are taken through the vision node's
current correction, so the new one is the old one plus what is left.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from flexarm_bringup.trials import trial_name
from flexarm_control.client import FlexarmClient
from flexarm_control.paper import TABLE_10
from flexarm_control.tool_calibration import (
    ReferenceCalibration,
    ToolCorrection,
    calibrate_against_reference,
    write_calibration,
)

VISION_NODE = 'flexarm_vision'


def calibrate_tool(client: FlexarmClient, reference_topic: str, path: Path,
                   timeout: float = 120.0, say: Callable[[str], None] = print,
                   ) -> tuple[ToolCorrection, ReferenceCalibration, dict[str, Any]]:
    """Calibrate (module docstring); the new correction, what was found and the details
    stored with it at ``path``."""
    current = ToolCorrection.from_list(client.node_parameter(VISION_NODE, 'tool_correction'))
    targets = [t.pose for t in TABLE_10]
    say(f'calibrating the camera against {reference_topic}: the arm moves RIGID (uncompensated) '
        f'to the {len(targets)} Table 10 poses')
    done = 0
    problem = ''      # why the last pose gave no measurement: the compensator's words

    def measure(target: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        nonlocal done, problem
        done += 1
        say(f'calibration pose {done}/{len(targets)}: x {target[0] * 1e3:.1f} mm, '
            f'y {target[1] * 1e3:.1f} mm, phi {np.degrees(target[2]):.2f} deg')
        result = client.move_to(*target, mode='rigid', timeout=timeout,
                                trial=trial_name('calibration', TABLE_10[done - 1].name, 'rigid'))
        if result.error_code != 0 or not result.measured:
            problem = result.error_string
            say(f'calibration pose {done}/{len(targets)}: no measurement ({problem})')
            return None
        m = result.measured_pose
        reference = client.poses_from(reference_topic, 3, timeout).mean(axis=0)
        return np.array([m.x, m.y, m.phi]), reference

    try:
        found = calibrate_against_reference(targets, measure)
    except ValueError as exc:          # too few poses measured: say why the camera did not
        raise ValueError(f'{exc}; the last pose without one: {problem}' if problem
                         else str(exc)) from None
    correction = current + found.correction
    details = {'reference': reference_topic, 'poses': found.poses,
               'spread': list(found.spread), 'stamp': time.strftime('%Y-%m-%dT%H:%M:%S')}
    write_calibration(path, correction, **details)
    client.set_node_parameter(VISION_NODE, 'tool_correction', correction.as_list())
    return correction, found, details
