"""Benchmark trials on a running graph: targets × modes, judged against the ground truth.

What ``flexarm demo`` and ``flexarm benchmark`` run. For every target and mode a MoveToPose
goal goes to the compensator; when it returns (arm settled and measured), the simulator's
ground-truth tip pose (``/sim/tip_pose_truth``, evaluation only — no control node reads it) is
the judge. Trials are named ``<prefix>/<target>/<mode>`` so a bag's outcomes can be matched.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass

import numpy as np

from flexarm_control import topics
from flexarm_control.client import FlexarmClient
from flexarm_control.kinematics import pose_error
from flexarm_control.modes import MODE_LABELS
from flexarm_msgs.msg import TipPose


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

    def as_dict(self) -> dict:
        return asdict(self)


class TruthMonitor:
    """Latest ground-truth tip pose, heard by the client node."""

    def __init__(self, client: FlexarmClient) -> None:
        self._lock = threading.Lock()
        self._latest: tuple[float, np.ndarray] | None = None
        client.create_subscription(TipPose, topics.TIP_POSE_TRUTH, self._on_truth, 10)

    def _on_truth(self, msg: TipPose) -> None:
        with self._lock:
            self._latest = (time.monotonic(), np.array([msg.pose.x, msg.pose.y, msg.pose.phi]))

    def after(self, since: float, client: FlexarmClient, timeout: float = 5.0) -> np.ndarray:
        """The first truth received after wall time ``since`` (spinning the client)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                if self._latest is not None and self._latest[0] > since:
                    return self._latest[1]
            client.spin_once(0.05)
        raise TimeoutError(f'no {topics.TIP_POSE_TRUTH} for {timeout:.0f} s')


def run_trials(client: FlexarmClient, truth: TruthMonitor,
               targets: Iterable[tuple[str, str, str, np.ndarray]], modes: Iterable[str],
               prefix: str, on_trial: Callable[[Trial], None] = lambda t: None,
               timeout: float = 600.0) -> list[Trial]:
    """Run every (name, group, region, target) in every mode; one :class:`Trial` each."""
    trials = []
    for name, group, region, target in targets:
        for mode in modes:
            start = time.monotonic()
            result = client.move_to(*target, mode=mode, trial=f'{prefix}/{name}/{mode}',
                                    timeout=timeout)
            reached = truth.after(time.monotonic(), client)
            position_error, angle_error = pose_error(target, reached)
            trial = Trial(
                name=name, group=group, region=region, mode=mode, target=target.tolist(),
                error_code=result.error_code, error_string=result.error_string,
                reached=reached.tolist(),
                measured=([result.measured_pose.x, result.measured_pose.y,
                           result.measured_pose.phi] if result.measured else None),
                position_error=position_error, angle_error=angle_error,
                iterations=result.iterations,
                compensation_iterations=result.compensation_iterations,
                data_distance=result.data_distance, prediction_std=result.prediction_std,
                seconds=time.monotonic() - start)
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
