"""Benchmark trials on a running graph: targets × modes, judged against the ground truth.

What ``flexarm demo`` and ``flexarm benchmark`` run. For every target and mode a MoveToPose
goal goes to the compensator; when it returns (arm settled and measured), the simulator's
ground-truth tip pose (``/sim/tip_pose_truth``, evaluation only — no control node reads it) is
the judge. Trials are named ``<prefix>/<target>/<mode>`` so a bag's outcomes can be matched.

The result holds only the last measurement of a goal; the tip measured after every move of a
CLOSED_LOOP goal comes from the goal's feedback (phase ``measuring``, one per move), kept in
:attr:`Trial.moves`. The last move is taken from the result as well, as its feedback may
arrive after the result.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

from flexarm_control.execution.modes import MODE_LABELS
from flexarm_core import topics
from flexarm_core.kinematics import pose_error, wrap_angle
from flexarm_msgs.action import MoveToPose
from flexarm_msgs.msg import PlanarPose, TipPose

# What a recorded outcome is (flexarm_recording.bag_tools): only GOAL rows are goals of
# the statistics and figures.
GOAL, DRY_RUN, CALIBRATION = 'goal', 'dry_run', 'calibration'

if TYPE_CHECKING:       # the client pulls in rclpy; bag_tools names trials without it
    from flexarm_control.ros.client import FlexarmClient

TRIAL_CSV_FIELDS = (
    'name', 'group', 'region', 'mode', 'error_code', 'error_string', 'iterations',
    'compensation_iterations', 'data_distance', 'prediction_std_mm', 'seconds',
    'target_x_mm', 'target_y_mm', 'target_phi_deg',
    'commanded_x_mm', 'commanded_y_mm', 'commanded_phi_deg',
    'predicted_dx_mm', 'predicted_dy_mm', 'predicted_dphi_deg',
    'measured_x_mm', 'measured_y_mm', 'measured_phi_deg',
    'measured_position_error_mm', 'measured_angle_error_deg',
    'truth_x_mm', 'truth_y_mm', 'truth_phi_deg',
    'truth_position_error_mm', 'truth_angle_error_deg')
MOVE_CSV_FIELDS = (
    'name', 'group', 'region', 'mode', 'move', 'measured_x_mm', 'measured_y_mm',
    'measured_phi_deg', 'measured_position_error_mm', 'measured_angle_error_deg')


@dataclass
class Trial:
    name: str
    group: str                    # e.g. 'table10', 'table9', 'random'
    region: str
    mode: str
    target: list[float]           # [m, m, rad]
    error_code: int
    error_string: str
    reached: list[float] | None   # ground truth after the goal [m, m, rad]
    measured: list[float] | None  # what the vision node measured
    position_error: float | None  # |truth - target| [m]
    angle_error: float | None     # [rad]
    iterations: int
    compensation_iterations: int
    data_distance: float          # of the commanded joints from the learned data [spacings]
    prediction_std: float         # the model's std of the predicted tip position [m]
    seconds: float                # wall time of the goal
    commanded: list[float]        # x* of the last move [m, m, rad]
    predicted_deflection: list[float]   # the plan's predicted deflection [m, m, rad]
    moves: list[list[float]]      # tip measured after each move [m, m, rad], in order

    def as_dict(self) -> dict:
        return asdict(self)

    def csv_row(self) -> dict[str, float | int | str]:
        """One row of :data:`TRIAL_CSV_FIELDS`: mm and deg, errors signed (pose minus target)
        but the position error; cells of what is unknown are left out (empty)."""
        row: dict[str, float | int | str] = {
            'name': self.name, 'group': self.group, 'region': self.region, 'mode': self.mode,
            'error_code': self.error_code, 'error_string': self.error_string,
            'iterations': self.iterations,
            'compensation_iterations': self.compensation_iterations,
            'data_distance': self.data_distance, 'prediction_std_mm': self.prediction_std * 1e3,
            'seconds': self.seconds, **_pose_cells('target', self.target),
            **_pose_cells('commanded', self.commanded),
            **_pose_cells('predicted', self.predicted_deflection, 'd')}
        for prefix, pose in (('measured', self.measured), ('truth', self.reached)):
            if pose is not None:
                row.update(_pose_cells(prefix, pose), **_error_cells(prefix, pose, self.target))
        return row

    def move_rows(self) -> list[dict[str, float | int | str]]:
        """One row of :data:`MOVE_CSV_FIELDS` per measured move."""
        return [{'name': self.name, 'group': self.group, 'region': self.region,
                 'mode': self.mode, 'move': i, **_pose_cells('measured', pose),
                 **_error_cells('measured', pose, self.target)}
                for i, pose in enumerate(self.moves, start=1)]


def trial_name(prefix: str, target: str, mode: str) -> str:
    """``<prefix>/<target>/<mode>``: the goal's trial name, so that a bag's outcomes can be
    matched to their target and mode."""
    return f'{prefix}/{target}/{mode}'


def trial_target(name: str) -> str | None:
    """The target of a trial named by :func:`trial_name`, None for another name."""
    parts = name.split('/')
    return parts[-2] if len(parts) >= 3 else None


def _pose_cells(prefix: str, pose: list[float], delta: str = '') -> dict[str, float]:
    return {f'{prefix}_{delta}x_mm': pose[0] * 1e3, f'{prefix}_{delta}y_mm': pose[1] * 1e3,
            f'{prefix}_{delta}phi_deg': math.degrees(pose[2])}


def _error_cells(prefix: str, pose: list[float], target: list[float]) -> dict[str, float]:
    return {f'{prefix}_position_error_mm': math.hypot(pose[0] - target[0],
                                                      pose[1] - target[1]) * 1e3,
            f'{prefix}_angle_error_deg': math.degrees(wrap_angle(pose[2] - target[2]))}


def _xyphi(pose: PlanarPose) -> list[float]:
    return [pose.x, pose.y, pose.phi]


class TruthMonitor:
    """The ground-truth tip pose after a goal, heard by the client node. ``/sim/tip_pose_truth``
    is subscribed only while a pose is asked for: the simulator builds and publishes the truth
    only while it has a subscriber (1000 messages a wall second at 10x real time), and the
    client would parse each one whenever it spins, all through the run."""

    def __init__(self, client: FlexarmClient) -> None:
        del client                              # subscribed to in after(), on demand

    def after(self, since: float, client: FlexarmClient, timeout: float = 5.0) -> np.ndarray:
        """The first truth received after wall time ``since`` (now or earlier: it subscribes
        now), spinning the client."""
        del since                               # whatever comes after subscribing is later
        [msg] = client.messages_from(topics.TIP_POSE_TRUTH, TipPose, 1, timeout,
                                     what='ground-truth poses')
        return np.array([msg.pose.x, msg.pose.y, msg.pose.phi])


def run_trials(client: FlexarmClient, truth: TruthMonitor,
               targets: Iterable[tuple[str, str, str, np.ndarray]], modes: Iterable[str],
               prefix: str, on_trial: Callable[[Trial], None] = lambda t: None,
               timeout: float = 600.0) -> list[Trial]:
    """Run every (name, group, region, target) in every mode; one :class:`Trial` each."""
    trials = []
    for name, group, region, target in targets:
        for mode in modes:
            start = time.monotonic()
            moves: dict[int, list[float]] = {}

            def heard(fb: MoveToPose.Feedback, moves: dict[int, list[float]] = moves) -> None:
                if fb.measured:
                    moves[fb.iteration] = _xyphi(fb.measured_pose)
            result = client.move_to(*target, mode=mode, trial=trial_name(prefix, name, mode),
                                    timeout=timeout, feedback=heard)
            if result.measured:
                moves[result.iterations] = _xyphi(result.measured_pose)
            reached = truth.after(time.monotonic(), client)
            position_error, angle_error = pose_error(target, reached)
            trial = Trial(
                name=name, group=group, region=region, mode=mode, target=target.tolist(),
                error_code=result.error_code, error_string=result.error_string,
                reached=reached.tolist(),
                measured=_xyphi(result.measured_pose) if result.measured else None,
                position_error=position_error, angle_error=angle_error,
                iterations=result.iterations,
                compensation_iterations=result.compensation_iterations,
                data_distance=result.data_distance, prediction_std=result.prediction_std,
                seconds=time.monotonic() - start, commanded=_xyphi(result.commanded_pose),
                predicted_deflection=_xyphi(result.predicted_deflection),
                moves=[moves[k] for k in sorted(moves)])
            trials.append(trial)
            on_trial(trial)
    return trials


def summarise(trials: list[Trial]) -> dict[str, dict[str, dict[str, float]]]:
    """Per group and mode: max and mean position [mm] / angle [deg] errors, successes."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for group in sorted({t.group for t in trials}):
        for mode in MODE_LABELS:
            chosen = [t for t in trials if t.group == group and t.mode == mode]
            if not chosen:
                continue
            pos = np.array([t.position_error for t in chosen]) * 1e3
            ang = np.degrees([t.angle_error for t in chosen])
            out.setdefault(group, {})[mode] = {
                'count': len(chosen), 'succeeded': sum(t.error_code == 0 for t in chosen),
                'max_mm': float(pos.max()), 'mean_mm': float(pos.mean()),
                'max_deg': float(ang.max()), 'mean_deg': float(ang.mean())}
    return out
