"""Hours of operation of one arm: do its nodes stay correct, safe and lean under everything an
operator floor does to them at once?

One graph of ``flexarm up`` (simulated robot at x10 real time, supervisor API) in a world where
only the payload changes (the simulator's error sources off but ``payload``, as
tests/test_drift_node.py's PAYLOAD_ONLY: the camera tells the truth up to its own noise and a
declared payload really loads the arm) runs for ``--arm-hours`` of the arm's time (``/clock``).
Meanwhile ``--operators`` clients (FlexarmClient, each in its own rclpy Context and thread, each
with its own seeded RNG) work it: the first collects ``--samples`` samples (default region) and
trains (``--kind``), then all take turns (a lock of this process, as operators who talk to
each other) at: goals of every mode to targets inside regions A and B (mostly short steps from
where the arm is); now and then a few samples more and a retraining; a payload declared
(``--payload`` kg) or taken back (0 kg), followed by a few samples and a retraining (a model
trained at one payload refuses PREDICTIVE goals at another; a refresh does not change that);
a refresh; and two motions sent at once from two clients (a pair: one must come back
ARM_BUSY, or both run one after the other; never both moving). Faults, one at a time, on the
arm's clock: ``--kill-every`` minutes of arm time after the last kill was over (the first half
a period after the warm-up) the vision node, the learner, or both (in turn) get a SIGKILL; the
supervisor restarts them. ``--blind-every`` minutes after the last blind spell (the first a
period after the warm-up) the camera is blinded for 5..``--blind-s`` arm seconds: the vision
node is paused with SIGSTOP and resumed with SIGCONT (the simulator's ``camera_rate`` is fixed
at its start; a paused vision node is what a withheld camera looks like downstream: no tip
pose comes; a SIGSTOP is no crash). A killed node is "back" once a new publisher of its
(tip_pose; the collection's status) appears; until 3 s after that (liveness-scaled) the graph
is degraded, as while blind: a goal that fails while it overlaps a degraded spell is an
expected failure (``failures.during_faults``). A restarted learner announces its configured
payload (0 kg), which the simulated arm follows: the operators declare theirs again. The run
ends once the arm time is reached, each mode has ``--goals`` goals sent, no fault is under
way, and every client's last action has ended (``--max-minutes``: earlier, ``cut_short``).

JSON (last line):

- ``goals``: MoveToPose goals sent per mode and ``total`` (a goal whose server was not there to
  take it is ``not_sent``); ``succeeded``: per mode, SUCCESSFUL results.
- ``unfinished_goals``: goals and collections whose client saw no terminal state (a result, or a
  rejection) within a liveness-scaled bound (moves 180 s, collections 60 s + 30 s a sample), or
  whose server went silent although nobody killed it. One whose learner was killed under it is
  ``lost_to_kills``, not unfinished. Must be 0.
- ``false_success``: SUCCESSFUL goals whose true final tip (``sim/tip_pose_truth``: the newest
  one stamped at or before the goal's outcome on compensator/outcomes, found by its unique
  trial name — the next motion may already move the arm when the result is read; a gap of more
  than ``TRUTH_GAP`` in the kept truth before that stamp leaves the goal unjudged)
  misses the target by more than the goal's bound plus ``camera_margin_mm``:
  CLOSED_LOOP, the compensator's ``position_tolerance``; PREDICTIVE (no tolerance given, never
  extrapolating), the 95 % position bound its plan stated (``position_error_bound``), unless
  the result warned that the camera measured it beyond that bound (then it said so: not
  judged); RIGID: none. ``camera_margin_mm``: 3 x the
  largest |vision - truth| of 20 settled frames at rest before the run, at least vision's
  settle.stability (0.02 mm): the server judges by the camera. ``unjudged``: successes whose
  truth or model was not known. Must be 0.
- ``concurrent_motion``: [s, wall] two different motions both moving the arm, from the clients'
  side: each goal or collection that moved has a window from its first feedback that shows it
  moving (MoveToPose PHASE_MOVING or later; CollectSamples/RefreshModel its first feedback) to
  its result (a motion whose learner was killed: to the kill). Motions are told apart by the
  result's ``motion`` (collections: the samples' ``motion``; refreshes: one each). Summed over
  pairs of windows: their overlap less ``DELIVERY_SLACK`` (0.5 s: a result and a feedback
  travel separately to two threads of this process). Must be 0.
- ``crashes``: node exits nobody caused: by a signal other than this benchmark's SIGKILL of that
  very process, or with a non-zero code (also when the graph is stopped at the end: SIGINT,
  SIGTERM or SIGKILL exits there are the stop's). ``crash_logs``: their last log lines. Must
  be 0.
- ``rss_growth_mb``: per node, RSS (psutil, with child processes) sampled every
  ``--sample-every`` s of wall (10): the mean over the last hour of arm time minus the mean
  over the first hour after the warm-up (each half the run when it is shorter than two hours).
  Like with like: each sample counts as its growth over its own process's base, its first
  sample after the warm-up (a restarted node's process: 20 s into its life), so a restarted
  node's fresh process is neither a leak nor a saving; for a node never restarted this is
  simply last minus first. Must be <= 20. ``rss_mb_series``: per node, [arm hour, MB] over
  the run (40 points), to tell a leak (climbing) from a warm-up (levelling off).
- ``fd_growth``: per node never restarted, open descriptors (psutil) at the end (after the
  clients stopped and 5 s) minus after the warm-up. Must be 0.
- ``lost_samples``: samples collections reported (result.collected, else the last feedback's
  k - skipped) that are not in the dataset file on disk (counted per collection by the samples'
  ``motion``; refreshes, whose feedback names no motion, per file). Must be 0.
- ``arm_hours``, ``wall_s`` (both from the clients' start to their end), ``achieved_rtf`` (arm
  time per wall second), ``restarts`` per node,
  ``refused_busy`` (ARM_BUSY results), ``pairs`` (outcomes of the two-at-once sends),
  ``failures`` (non-successes other than ARM_BUSY by kind, mode and code or client-side end:
  ``during_faults`` overlapping a degraded spell, ``other``: e.g. a PREDICTIVE goal refused at a
  payload its model was not trained at), ``faults``, ``payload_reverts`` (the arm's payload
  changed with no client declaring it: a restarted learner announces its configured one),
  ``camera_error_mm`` (|measured - true| of measured successes).

    python tests/endurance/soak.py [--arm-hours 2] [--goals 500] [--seed 1] [--json]
    python tests/endurance/soak.py --smoke --json    (about 40 s alone: 0.02 h, a goal a mode)
"""
from __future__ import annotations

import argparse
import contextlib
import json
import math
import queue
import random
import signal
import tempfile
import threading
import time
import traceback
import uuid
from collections import Counter, defaultdict, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import psutil
import rclpy
from rclpy.context import Context
from rclpy.qos import QoSDurabilityPolicy, QoSProfile
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64

from flexarm_bringup.launcher import node_name
from flexarm_bringup.supervisor import Graph
from flexarm_cli.experiment import reserved_domain
from flexarm_control.ros.client import (
    FlexarmClient,
    GoalFailed,
    GoalRejected,
    GoalRun,
    ServerLost,
)
from flexarm_core import liveness, topics
from flexarm_core.kinematics import ArmGeometry, UnreachableError, inverse
from flexarm_core.params import load_config
from flexarm_core.processes import descendants
from flexarm_core.ros.taken import Taken, take
from flexarm_deflection.dataset import load_dataset
from flexarm_msgs.action import CollectSamples, MoveToPose, RefreshModel
from flexarm_msgs.msg import GoalOutcome, TipPose

READY_S = 120.0          # [s, wall] bound of the graph's bring-up
BACK_S = 120.0           # [s, wall] bound of a killed node's return
GRACE_S = 3.0            # [s, wall] degraded after a node is back or the camera sees again
MOVE_S = 180.0           # [s, wall] a goal's terminal state comes within this...
COLLECT_S = (60.0, 30.0)  # ... a collection's within this + per sample (all liveness-scaled)
TRAIN_S = 180.0
DELIVERY_SLACK = 0.5     # [s, wall] of overlap two motion windows may show (docstring)
RSS_SETTLE = 20.0        # [s, wall] of a process's life before its base RSS sample
HOUR = 3600.0
MODES = ('rigid', 'predictive', 'closed_loop')
STEP = (0.03, 0.03, 0.05)   # [m, m, rad] largest short step of a target from the last one
ROOM = (0.03, 0.03, 0.0436)  # [m, m, rad] a target's reach each way: the learner's coverage
DATASET = 'soak'
VISION, LEARNER = node_name('vision'), node_name('learner')
# Payload changes on, every other error source off (tests/test_drift_node.py)
PAYLOAD_ONLY = {'error_sources': {'enabled': True, **{
    source: {'enabled': source == 'payload'}
    for source in ('repeatability', 'hysteresis', 'thermal', 'camera', 'payload')}}}
# The topic a node's fresh process publishes on once it is back (a new publisher of it)
BACK_TOPIC = {VISION: topics.absolute(topics.TIP_POSE),
              LEARNER: topics.absolute(topics.COLLECT_SAMPLES) + '/_action/status'}
KILLS = ((VISION,), (LEARNER,), (VISION, LEARNER))     # in turn
STOP_EXITS = (0, -signal.SIGINT, -signal.SIGTERM, -signal.SIGKILL)   # Graph.stop's signals
# What an operator does next, by weight
STEPS = (('goal', 70), ('pair', 12), ('collect', 7), ('payload', 5), ('refresh', 4))
SMOKE = {'arm_hours': 0.02, 'goals': 1, 'samples': 8, 'kill_every': 1.0, 'blind_every': 0.25,
         'sample_every': 2.0, 'max_minutes': 6.0}
LATCHED = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
TRUTH_QUEUE = 10000     # sim/tip_pose_truth messages between two looks (1000 a wall second)
TRUTH_KEPT = 60000      # true tips kept to judge a goal by (a minute of wall time)
TRUTH_EVERY = 0.1       # [s, wall] between two looks at the truth (its own thread)
TRUTH_GAP = 0.1         # [s, sim] the newest truth before a goal's end may be older by this


def stamp_ns(stamp: Any) -> int:
    return stamp.sec * 10**9 + stamp.nanosec


def code_names(result: type) -> dict[int, str]:
    return {v: k for k, v in vars(result).items() if k.isupper() and isinstance(v, int)}


NAMES = {'move': code_names(MoveToPose.Result), 'collect': code_names(CollectSamples.Result),
         'refresh': code_names(RefreshModel.Result)}
BUSY = {'move': MoveToPose.Result.ARM_BUSY, 'collect': CollectSamples.Result.ARM_BUSY,
        'refresh': RefreshModel.Result.ARM_BUSY}


@dataclass
class Outcome:
    """One goal (move, collection or refresh) as its client saw it."""

    kind: str                     # move | collect | refresh
    mode: str = ''                # of a move
    client: str = ''
    sent: float = 0.0             # [s, monotonic]
    end: float = 0.0
    status: str = ''              # result | rejected | lost | unfinished | not_sent | no_code
    result: Any = None
    error: str = ''
    moving_since: float | None = None
    motion: str = ''
    reported: int = 0             # samples the feedback reported collected
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)
    trial: str = ''                     # of a move: unique, to find its outcome
    truth_error: float | None = None    # [m] of a success
    bound: float | None = None          # [m] its bound (None: none)

    @property
    def code(self) -> int | None:
        return None if self.result is None else self.result.error_code

    @property
    def label(self) -> str:
        """Its terminal state in words: a result code's name, or the status."""
        if self.result is not None:
            return NAMES[self.kind].get(self.code, str(self.code))
        return self.status


@dataclass
class Spell:
    """A degraded time of the graph [monotonic s]: a kill until back, or a blind camera."""

    what: str
    start: float
    end: float = math.inf
    nodes: tuple[str, ...] = ()


@dataclass
class Ledger:
    """What the operators did, shared between their threads."""

    lock: threading.Lock = field(default_factory=threading.Lock)
    outcomes: list[Outcome] = field(default_factory=list)
    trainings: Counter[str] = field(default_factory=Counter)
    pairs: Counter[str] = field(default_factory=Counter)
    payloads: list[tuple[float, float]] = field(default_factory=list)  # (monotonic, kg) declared
    errors: list[str] = field(default_factory=list)     # an operator's own exceptions

    def add(self, outcome: Outcome) -> None:
        with self.lock:
            self.outcomes.append(outcome)

    def sent(self, mode: str) -> int:
        with self.lock:
            return sum(1 for o in self.outcomes if o.kind == 'move' and o.mode == mode
                       and o.status != 'not_sent')


class Observer:
    """This benchmark's own node: the sim clock, the true tip, the models and the payload, all
    taken when looked at (no executor, no wake-up per message: the truth comes 1000 times a
    wall second), behind one lock for every thread."""

    def __init__(self, domain: int) -> None:
        self._context = Context()
        rclpy.init(context=self._context, domain_id=domain)
        self.node = rclpy.create_node('flexarm_soak_observer', context=self._context)
        group = Taken()
        sub = self.node.create_subscription
        self._clock = sub(Clock, topics.CLOCK, lambda _: None, 1, callback_group=group)
        self._truth = sub(TipPose, topics.TIP_POSE_TRUTH, lambda _: None, TRUTH_QUEUE,
                          callback_group=group)
        self._outcomes = sub(GoalOutcome, topics.OUTCOMES, lambda _: None, 100,
                             callback_group=group)
        self.truths: deque[tuple[int, TipPose]] = deque(maxlen=TRUTH_KEPT)   # (stamp ns, msg)
        self.ended: dict[str, int] = {}      # trial -> its outcome's stamp [ns, sim]
        self._group = group
        self._payload = sub(Float64, topics.PAYLOAD, lambda _: None, QoSProfile(
            depth=20, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL), callback_group=group)
        self.lock = threading.Lock()
        self.sim = 0.0
        self.payloads: list[tuple[float, float]] = []     # (monotonic, kg) heard on /payload
        self._stop = threading.Event()
        self._taker = threading.Thread(target=self._keep_taking, name='flexarm_soak_truth',
                                       daemon=True)
        self._taker.start()

    def clock(self) -> float:
        """The newest sim time [s] heard."""
        with self.lock:
            msg = take(self._clock)
            if msg is not None:
                self.sim = msg.clock.sec + msg.clock.nanosec * 1e-9
            return self.sim

    def poll(self) -> None:
        """Take the payloads announced since the last look."""
        with self.lock:
            while (msg := take(self._payload)) is not None:
                self.payloads.append((time.monotonic(), msg.data))

    def take_truth(self) -> None:
        """Keep the true tips and the goals' end stamps that came since the last look (by its
        own thread every ``TRUTH_EVERY``, and by every judge: the queue
        holds 10 s of the truth, so a stalled main loop loses none of it)."""
        with self.lock:
            while (msg := take(self._truth)) is not None:
                self.truths.append((stamp_ns(msg.header.stamp), msg))
            while (outcome := take(self._outcomes)) is not None:
                self.ended[outcome.trial] = stamp_ns(outcome.stamp)

    def _keep_taking(self) -> None:
        while not self._stop.wait(TRUTH_EVERY):
            self.take_truth()

    def truth(self) -> TipPose | None:
        """The newest settled true tip; None if none is at hand."""
        self.take_truth()
        with self.lock:
            return next((msg for _, msg in reversed(self.truths) if msg.settled), None)

    def truth_at_end(self, trial: str, timeout: float) -> TipPose | None:
        """The true tip where the goal ``trial`` ended: the newest one stamped at or before
        its outcome (the next motion may already move the arm when the result is read); None
        if its outcome does not come within ``timeout`` s, or the kept truth has a gap of more
        than ``TRUTH_GAP`` before it (a truth from before the gap may be the last target's)."""
        deadline = time.monotonic() + timeout
        while True:
            self.take_truth()
            with self.lock:
                end = self.ended.pop(trial, None)
                if end is not None:
                    stamp, msg = next(((stamp, msg) for stamp, msg in reversed(self.truths)
                                       if stamp <= end), (None, None))
                    return msg if stamp is not None and end - stamp <= TRUTH_GAP * 1e9 else None
            if time.monotonic() > deadline:
                return None
            time.sleep(0.05)

    def camera_error(self, frames: int, timeout: float) -> float:
        """[m] The largest |vision - truth| of ``frames`` valid, settled frames at rest.
        ``/tip_pose`` is subscribed for this alone: the graph measures only for a subscriber,
        and the soak's operators' own measurements are what it is to run."""
        with self.lock:
            tips = self.node.create_subscription(TipPose, topics.TIP_POSE, lambda _: None, 50,
                                                 callback_group=self._group)
        errors: list[float] = []
        deadline = time.monotonic() + timeout
        try:
            while len(errors) < frames:
                if time.monotonic() > deadline:
                    raise TimeoutError(f'{len(errors)} of {frames} settled tip poses in '
                                       f'{timeout:.0f} s')
                with self.lock:
                    msg = take(tips)
                truth = self.truth() if msg is not None and msg.valid and msg.settled else None
                if truth is None:
                    time.sleep(0.02)
                    continue
                errors.append(math.hypot(msg.pose.x - truth.pose.x, msg.pose.y - truth.pose.y))
        finally:
            with self.lock:
                self.node.destroy_subscription(tips)
        return max(errors)

    def publishers(self, topic: str) -> set[bytes]:
        return {bytes(info.endpoint_gid)
                for info in self.node.get_publishers_info_by_topic(topic)}

    def close(self) -> None:
        self._stop.set()
        self._taker.join()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self._context)


@dataclass
class Pair:
    """Two motions sent at once: the partner's half, handed over to its thread."""

    barrier: threading.Barrier
    done: threading.Event = field(default_factory=threading.Event)
    outcome: Outcome | None = None


class Soak:
    """What the operators share: the turn, the arm's last target, what a goal is judged by."""

    def __init__(self, args: argparse.Namespace, observer: Observer, data: Path) -> None:
        self.args, self.observer, self.data = args, observer, data
        self.ledger = Ledger()
        self.turn = threading.Lock()
        self.stop = threading.Event()
        self.model_ready = threading.Event()
        self.warm = threading.Event()
        self.at: tuple[float, float, float] | None = None
        self.payload = 0.0
        self.redeclare = threading.Event()
        self.operators: list[Operator] = []
        regions = load_config('learner.yaml', node_name=LEARNER)['regions']
        self.regions = {name: regions[name] for name in ('A', 'B')}
        self.geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
        self.tolerance = 0.0      # the compensator's, read at start
        self.margin = 0.0                                     # [m] camera_margin
        self.camera_errors: list[float] = []    # [m] |measured - true| of measured successes

    def target(self, rng: random.Random, region: str) -> tuple[float, float, float]:
        """A target inside ``region`` (its inner 60 %) that the rigid arm reaches with room
        for the compensation (:data:`ROOM` each way): a short step from where the arm is, or
        anywhere in it when the arm is elsewhere (or one time in ten)."""
        box = self.regions[region]
        inner = [(lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo))
                 for lo, hi in (box['x'], box['y'], box['phi'])]
        for _ in range(100):
            at = self.at
            inside = at is not None and all(lo <= v <= hi for v, (lo, hi) in zip(at, inner))
            if not inside or rng.random() < 0.1:
                pose = tuple(rng.uniform(lo, hi) for lo, hi in inner)
            else:
                pose = tuple(min(hi, max(lo, v + rng.uniform(-step, step)))
                             for v, step, (lo, hi) in zip(at, STEP, inner))
            if self.reachable(pose):
                return pose
        raise RuntimeError(f'no reachable target in region {region} in 100 draws')

    def reachable(self, pose: tuple[float, float, float]) -> bool:
        try:
            for axis in range(3):
                for sign in (-1, 1):
                    moved = np.array(pose)
                    moved[axis] += sign * ROOM[axis]
                    inverse(self.geometry, moved)
        except UnreachableError:
            return False
        return True

    def judge(self, outcome: Outcome) -> None:
        """A successful move's true error and bound (module docstring)."""
        result = outcome.result
        truth = self.observer.truth_at_end(outcome.trial, liveness.limit(10.0))
        self.at = outcome.target
        if truth is not None:
            x, y, _ = outcome.target
            outcome.truth_error = math.hypot(truth.pose.x - x, truth.pose.y - y)
            if result.measured:
                with self.ledger.lock:
                    self.camera_errors.append(math.hypot(result.measured_pose.x - truth.pose.x,
                                                         result.measured_pose.y - truth.pose.y))
        if outcome.mode == 'closed_loop':
            outcome.bound = self.tolerance + self.margin
        elif outcome.mode == 'predictive' and "beyond the plan's 95 % bound" not in (
                result.error_string):
            outcome.bound = result.position_error_bound + self.margin    # NaN: unjudged


class Operator:
    """One client of the arm in its own context and thread (module docstring)."""

    def __init__(self, index: int, domain: int, soak: Soak) -> None:
        self.index, self.soak = index, soak
        self.name = f'flexarm_soak_operator_{index}'
        self.rng = random.Random(soak.args.seed * 1000 + index)
        self._context = Context()
        rclpy.init(context=self._context, domain_id=domain)
        self.client = FlexarmClient(self.name, context=self._context)
        self.requests: queue.Queue[Pair] = queue.Queue()
        self.region = self.rng.choice(('A', 'B'))
        self.thread = threading.Thread(target=self._run, name=self.name, daemon=True)

    # --- the loop ---------------------------------------------------------------------------
    def _run(self) -> None:
        soak = self.soak
        try:
            self.client.wait_until_ready(timeout=liveness.limit(60.0))
            if self.index == 0:
                with soak.turn:
                    self._initial()
            while not soak.model_ready.wait(0.2):
                if soak.stop.is_set():
                    return
            while not soak.stop.is_set():
                self._serve_pair()
                if soak.turn.acquire(timeout=0.1):
                    try:
                        if not soak.stop.is_set():
                            self._step()
                    finally:
                        soak.turn.release()
                    time.sleep(self.rng.uniform(0.05, 0.4))   # the others' turn
        except Exception:    # the benchmark's own bug: reported, never silent
            with soak.ledger.lock:
                soak.ledger.errors.append(f'{self.name}: {traceback.format_exc()[-1500:]}')
        finally:
            while not self.requests.empty():       # no partner waits on a gone operator
                self.requests.get_nowait().barrier.abort()

    def _initial(self) -> None:
        """Samples and a model to begin with, until both are there."""
        soak = self.soak
        while not soak.stop.is_set():
            collected = self.collect(soak.args.samples, '', seed=1)
            if collected.result is not None and collected.result.collected >= 8 \
                    and self.train():
                soak.model_ready.set()
                return
            time.sleep(1.0)

    def _step(self) -> None:
        soak, rng = self.soak, self.rng
        if soak.redeclare.is_set():           # a restarted learner forgot the payload
            with contextlib.suppress(TimeoutError, ValueError, RuntimeError):
                self.client.set_payload(soak.payload, timeout=liveness.limit(10.0))
                soak.redeclare.clear()
                self._declared(soak.payload)
        if rng.random() < 0.1:
            self.region = 'B' if self.region == 'A' else 'A'
        step = rng.choices([s for s, _ in STEPS], [w for _, w in STEPS])[0]
        if step == 'goal':
            self.move(self._mode(), soak.target(rng, self.region))
        elif step == 'pair':
            self._pair()
        elif step == 'collect':
            self.collect(3, rng.choice(('A', 'B', '')), seed=rng.randrange(1, 10**6))
            self.train()
        elif step == 'payload':
            self._payload()
        else:
            self.refresh(3, self.region)

    def _mode(self) -> str:
        """A mode at random, one time in two the one with the fewest goals sent."""
        if self.rng.random() < 0.5:
            return min(MODES, key=self.soak.ledger.sent)
        return self.rng.choice(MODES)

    def _declared(self, kg: float) -> None:
        with self.soak.ledger.lock:
            self.soak.ledger.payloads.append((time.monotonic(), kg))

    def _payload(self) -> None:
        """Declare the payload or take it back, then teach the model the new one."""
        soak = self.soak
        kg = 0.0 if soak.payload else soak.args.payload
        self._declared(kg)        # before: /payload may come back before the call returns
        try:
            self.client.set_payload(kg, timeout=liveness.limit(10.0))
        except (TimeoutError, ValueError, RuntimeError) as exc:
            with soak.ledger.lock:
                soak.ledger.trainings[f'payload refused: {type(exc).__name__}'] += 1
            return
        soak.payload = kg      # a refresh would not do: a model trained at one payload
        self.collect(4, self.region, seed=self.rng.randrange(1, 10**6))   # refuses another
        self.train()

    # --- two motions at once ----------------------------------------------------------------
    def _pair(self) -> None:
        soak = self.soak
        others = [o for o in soak.operators if o is not self]
        if not others:
            return
        partner = self.rng.choice(others)
        pair = Pair(threading.Barrier(2, timeout=liveness.limit(30.0)))
        partner.requests.put(pair)
        try:
            pair.barrier.wait()
        except threading.BrokenBarrierError:
            return
        mine = self.move(self._mode(), soak.target(self.rng, self.region))
        if not pair.done.wait(liveness.limit(MOVE_S + 60.0)) or pair.outcome is None:
            soak.ledger.pairs['partner_unfinished'] += 1
            return
        theirs = pair.outcome
        busy = [o.code == BUSY[o.kind] for o in (mine, theirs)]
        with soak.ledger.lock:
            soak.ledger.pairs['one_busy' if sum(busy) == 1 else 'both_busy' if all(busy)
                              else 'both_succeeded' if mine.code == theirs.code == 0
                              else 'other'] += 1

    def _serve_pair(self) -> None:
        try:
            pair = self.requests.get_nowait()
        except queue.Empty:
            return
        try:
            pair.barrier.wait()
        except threading.BrokenBarrierError:
            return
        try:
            if self.rng.random() < 0.7:
                pair.outcome = self.move(self._mode(), self.soak.target(self.rng, self.region))
            else:
                pair.outcome = self.collect(2, self.region, seed=self.rng.randrange(1, 10**6))
        finally:
            pair.done.set()

    # --- goals ------------------------------------------------------------------------------
    def run_goal(self, outcome: Outcome, start: Callable[[Callable[[Any], None]], GoalRun],
                 bound: float, moving: Callable[[Any], bool]) -> Outcome:
        """Send a goal (``start`` with its feedback callback) and follow it to its terminal
        state, or give up after ``bound`` seconds (unfinished)."""
        outcome.client = self.name

        def on_feedback(feedback: Any) -> None:
            if outcome.moving_since is None and moving(feedback):
                outcome.moving_since = time.monotonic()
            if outcome.kind == 'collect':
                outcome.reported = feedback.k - feedback.skipped
                outcome.motion = feedback.last_sample.motion or outcome.motion
        outcome.sent = time.monotonic()
        try:
            run = start(on_feedback)
        except (TimeoutError, RuntimeError) as exc:      # its server is not there to take it
            outcome.status, outcome.error, outcome.end = 'not_sent', str(exc), time.monotonic()
            self.soak.ledger.add(outcome)
            return outcome
        deadline = outcome.sent + bound
        try:
            while not run.done(0.1):
                if time.monotonic() > deadline:
                    outcome.status = 'unfinished'
                    outcome.error = f'no terminal state within {bound:.0f} s'
                    with contextlib.suppress(TimeoutError, RuntimeError):
                        run.cancel(5.0)
                    break
            else:
                outcome.status, outcome.result = 'result', run.result()
        except GoalRejected as exc:
            outcome.status, outcome.error = 'rejected', str(exc)
        except ServerLost as exc:
            outcome.status, outcome.error = 'lost', str(exc)
        except GoalFailed as exc:
            outcome.status, outcome.error = 'no_code', str(exc)
        except (TimeoutError, RuntimeError) as exc:
            outcome.status, outcome.error = 'unfinished', str(exc)
        outcome.end = time.monotonic()
        self.soak.ledger.add(outcome)
        return outcome

    def move(self, mode: str, target: tuple[float, float, float]) -> Outcome:
        outcome = Outcome('move', mode, target=target, trial=f'soak {mode} {uuid.uuid4().hex}')
        bound = liveness.limit(MOVE_S)
        self.run_goal(outcome, lambda feedback: self.client.move_async(
            *target, mode, trial=outcome.trial, timeout=bound, feedback=feedback), bound,
            lambda fb: fb.phase != MoveToPose.Feedback.PHASE_PLANNING)
        if outcome.result is not None:
            outcome.motion = outcome.result.motion
            if outcome.code == MoveToPose.Result.SUCCESSFUL:
                self.soak.judge(outcome)
        return outcome

    def collect(self, count: int, region: str, seed: int) -> Outcome:
        outcome = Outcome('collect')
        bound = liveness.limit(COLLECT_S[0] + COLLECT_S[1] * count)
        self.run_goal(outcome, lambda feedback: self.client.collect_async(
            count, region, seed=seed, dataset=DATASET, timeout=bound, feedback=feedback),
            bound, lambda fb: True)
        return outcome

    def refresh(self, count: int, region: str) -> Outcome:
        outcome = Outcome('refresh', motion=f'refresh-{uuid.uuid4().hex[:8]}')
        bound = liveness.limit(COLLECT_S[0] + COLLECT_S[1] * count)
        goal = RefreshModel.Goal(count=count, region=region, force=True)
        self.run_goal(outcome, lambda feedback: GoalRun(
            self.client, self.client._refresh, goal, bound, feedback), bound, lambda fb: True)
        return outcome

    def train(self) -> bool:
        try:
            response = self.client.train(self.soak.args.kind, dataset=DATASET,
                                         timeout=liveness.limit(TRAIN_S))
        except (TimeoutError, RuntimeError) as exc:
            self.soak.ledger.trainings[f'failed: {type(exc).__name__}'] += 1
            return False
        self.soak.ledger.trainings['ok' if response.success else 'refused'] += 1
        return response.success

    def close(self) -> None:
        self.client.destroy_node()
        rclpy.try_shutdown(context=self._context)


# --- the graph's side ------------------------------------------------------------------------
@dataclass
class Proc:
    """One node process's samples: (sim s, wall s, RSS MB)."""

    name: str
    pid: int
    started: float                     # [monotonic s] first seen
    restarted: bool = False            # a restarted node's process
    samples: list[tuple[float, float, float]] = field(default_factory=list)
    base: float | None = None          # [MB] its first sample RSS_SETTLE s into its life


def tree_rss_mb(pid: int) -> float:
    """The resident set [MB] of ``pid`` with its child processes (a learner's training
    worker); 0 once they are gone."""
    total = 0.0
    for member in descendants([pid]):
        with contextlib.suppress(psutil.Error):
            total += psutil.Process(member).memory_info().rss / 2**20
    return total


def fds(pid: int) -> int | None:
    """How many descriptors the process ``pid`` has open (None once it is gone)."""
    try:
        return psutil.Process(pid).num_fds()
    except psutil.Error:
        return None


class Watch:
    """The graph's nodes: exits told apart from the kills sent, restarts, process samples."""

    def __init__(self, graph: Graph, say: Callable[[str], None], every: float) -> None:
        self.graph, self.say, self.every = graph, say, every
        self.killed: set[int] = set()          # pids this benchmark sent SIGKILL
        self.crashes: list[str] = []
        self.procs: dict[int, Proc] = {}
        self.warm_at: float | None = None      # [monotonic s]
        self.fd_warm: dict[str, int] = {}
        self._last_sample = 0.0

    def check(self) -> None:
        """Account every exit since the last look, then let the supervisor restart."""
        seen = []
        for name, node in self.graph.nodes.items():
            code = node.returncode
            if code is None or node.reported:
                continue
            seen.append(name)
            if not (node.process.pid in self.killed and code == -signal.SIGKILL):
                self.crash(name, code, node.log_tail(30))
        dead = self.graph.check()
        for name in set(dead) - set(seen):     # died between the two looks: its code is gone
            self.crash(name, None, self.graph.nodes[name].log_tail(30))

    def crash(self, name: str, code: int | None, tail: str) -> None:
        self.crashes.append(f'{name} exit {code}:\n{tail}')
        self.say(f'CRASH {name} exit {code}')

    def kill(self, name: str) -> None:
        node = self.graph.nodes[name]
        self.killed.add(node.process.pid)
        node.signal(signal.SIGKILL)

    def sample(self, sim: float, force: bool = False) -> None:
        now = time.monotonic()
        if not force and now - self._last_sample < self.every:
            return
        self._last_sample = now
        for name, node in self.graph.nodes.items():
            if node.process is None or node.returncode is not None:
                continue
            pid = node.process.pid
            proc = self.procs.setdefault(pid, Proc(name, pid, now, restarted=node.restarts > 0))
            rss = tree_rss_mb(pid)
            proc.samples.append((sim, now, rss))
            if proc.base is None and self.counts(proc, now):
                proc.base = rss

    def counts(self, proc: Proc, wall: float) -> bool:
        """Whether a sample of ``proc`` at ``wall`` counts: after the warm-up, and for a
        restarted node's process RSS_SETTLE s into its life."""
        return self.warm_at is not None and wall >= self.warm_at and (
            not proc.restarted or wall >= proc.started + RSS_SETTLE)

    def warmed(self, sim: float) -> None:
        self.warm_at = time.monotonic()
        self.sample(sim, force=True)
        self.fd_warm = {name: n for name, node in self.graph.nodes.items()
                        if node.process and (n := fds(node.process.pid)) is not None}

    def rss_growth(self, warm: float, end: float) -> dict[str, float | None]:
        """Per node (module docstring): mean growth over its process's base, last window
        minus first."""
        window = min(HOUR, (end - warm) / 2)
        first, last = defaultdict(list), defaultdict(list)
        for proc in self.procs.values():
            if proc.base is None:
                continue
            for sim, wall, rss in proc.samples:
                if not self.counts(proc, wall):
                    continue
                if warm <= sim <= warm + window:
                    first[proc.name].append(rss - proc.base)
                if end - window <= sim <= end:
                    last[proc.name].append(rss - proc.base)
        return {name: (round(sum(last[name]) / len(last[name])
                             - sum(first[name]) / len(first[name]), 2)
                       if first[name] and last[name] else None)
                for name in self.graph.nodes}

    def rss_series(self, start: float, points: int = 40) -> dict[str, list[list[float]]]:
        """Per node, its processes' RSS over the run: at most ``points`` [arm hour, MB] pairs
        (a restarted node's processes one after the other): a leak climbs, a warm-up levels."""
        out: dict[str, list[list[float]]] = {}
        for name in self.graph.nodes:
            samples = sorted((sim, rss) for proc in self.procs.values() if proc.name == name
                             for sim, _, rss in proc.samples)
            step = max(1, len(samples) // points)
            out[name] = [[round((sim - start) / HOUR, 3), round(rss, 1)]
                         for sim, rss in samples[::step]]
        return out

    def fd_growth(self) -> dict[str, int]:
        out = {}
        for name, node in self.graph.nodes.items():
            if node.restarts or name not in self.fd_warm or node.process is None:
                continue
            now = fds(node.process.pid)
            if now is not None:
                out[name] = now - self.fd_warm[name]
        return out


class Faults:
    """The kills and blind spells, one at a time, on the arm's clock (module docstring)."""

    def __init__(self, args: argparse.Namespace, watch: Watch, observer: Observer,
                 soak: Soak, say: Callable[[str], None]) -> None:
        self.args, self.watch, self.observer, self.soak, self.say = (args, watch, observer,
                                                                      soak, say)
        self.rng = random.Random(args.seed + 7)
        self.spells: list[Spell] = []
        self.kills = self.blinds = 0
        self.next_kill = self.next_blind = math.inf
        self._current: Spell | None = None
        self._old: dict[str, set[bytes]] = {}
        self._until = 0.0                 # blind: resume at this sim time
        self._back: float | None = None   # [monotonic s] when every killed node was back
        self.slow_back: list[str] = []

    def start(self, sim: float) -> None:
        """The first kill half a period after the warm-up, the first blind spell a period."""
        self.next_kill = sim + 30.0 * self.args.kill_every if self.args.kill_every else math.inf
        self.next_blind = sim + 60.0 * self.args.blind_every if self.args.blind_every \
            else math.inf

    def step(self, sim: float, start_new: bool = True) -> None:
        """Follow the current spell; start the next fault that is due (the one due first),
        if ``start_new``. A period counts from the end of the last fault of its kind."""
        spell = self._current
        if spell is None:
            if start_new and min(self.next_kill, self.next_blind) <= sim:
                (self._kill if self.next_kill <= self.next_blind else self._blind)(sim)
            return
        now = time.monotonic()
        if spell.what == 'blind':
            if sim >= self._until:
                self.resume()
                self.next_blind = sim + 60.0 * self.args.blind_every
                self._close(now + liveness.limit(GRACE_S))
            return
        if self._back is None:
            back = all(self.observer.publishers(BACK_TOPIC[n]) - self._old[n]
                       for n in spell.nodes)
            if back:
                self._back = now
            elif now - spell.start > liveness.limit(BACK_S):
                self.slow_back.append(f'{"+".join(spell.nodes)} not back after '
                                      f'{now - spell.start:.0f} s')
                self._back = now
        elif now >= self._back + liveness.limit(GRACE_S):
            if LEARNER in spell.nodes and self.soak.payload:
                self.soak.redeclare.set()
            self.next_kill = sim + 60.0 * self.args.kill_every
            self._close(now)

    def _close(self, end: float) -> None:
        self._current.end = end
        self.say(f'{self._current.what} {"+".join(self._current.nodes)} over after '
                 f'{end - self._current.start:.1f} s')
        self._current = None

    def _kill(self, sim: float) -> None:
        nodes = KILLS[self.kills % len(KILLS)]
        self.kills += 1
        self.next_kill = math.inf             # set when it is over
        self._old = {n: self.observer.publishers(BACK_TOPIC[n]) for n in nodes}
        self._back = None
        self._current = Spell('kill', time.monotonic(), nodes=nodes)
        self.spells.append(self._current)
        for name in nodes:
            self.watch.kill(name)
        self.say(f'SIGKILL {"+".join(nodes)} at arm time {sim:.0f} s')

    def _blind(self, sim: float) -> None:
        self.blinds += 1
        self.next_blind = math.inf
        self._until = sim + self.rng.uniform(5.0, self.args.blind_s)
        self._current = Spell('blind', time.monotonic(), nodes=(VISION,))
        self.spells.append(self._current)
        self.watch.graph.nodes[VISION].signal(signal.SIGSTOP)
        self.say(f'camera blind (SIGSTOP {VISION}) until arm time {self._until:.0f} s')

    def resume(self) -> None:
        """SIGCONT the vision node if it is paused (also at the end)."""
        if self._current is not None and self._current.what == 'blind':
            self.watch.graph.nodes[VISION].signal(signal.SIGCONT)

    def busy(self) -> bool:
        return self._current is not None


# --- figures ---------------------------------------------------------------------------------
def overlaps(outcome: Outcome, spells: list[Spell]) -> bool:
    return any(s.start <= outcome.end and outcome.sent <= s.end for s in spells)


def killed_under(outcome: Outcome, spells: list[Spell]) -> float | None:
    """The time the learner was killed while this collection or refresh ran, if it was."""
    for s in spells:
        if s.what == 'kill' and LEARNER in s.nodes and outcome.sent <= s.start <= outcome.end:
            return s.start
    return None


def concurrency(outcomes: list[Outcome], spells: list[Spell]) -> tuple[float, list[str]]:
    """[s] Overlap of the moving windows of different motions, beyond the slack; examples."""
    windows = []
    for o in outcomes:
        if o.moving_since is None:
            continue
        end = o.end
        if o.kind != 'move' and (killed := killed_under(o, spells)) is not None:
            end = min(end, killed)
        windows.append((o.moving_since, end, o.motion or f'{o.client}@{o.sent:.3f}', o))
    windows.sort(key=lambda w: w[0])
    total, examples = 0.0, []
    for i, (_, end, motion, o) in enumerate(windows):
        for start2, end2, motion2, o2 in windows[i + 1:]:
            if start2 >= end:
                break
            excess = min(end, end2) - start2 - DELIVERY_SLACK
            if motion2 != motion and excess > 0:
                total += excess
                if len(examples) < 5:
                    examples.append(f'{o.kind} {motion} ({o.client}) and {o2.kind} {motion2} '
                                    f'({o2.client}): {excess + DELIVERY_SLACK:.2f} s')
    return total, examples


def lost_samples(outcomes: list[Outcome], data: Path) -> tuple[int, list[str]]:
    """Samples reported collected that are not on disk (module docstring)."""
    on_disk: dict[Path, list[Any]] = {}

    def samples(path: Path) -> list[Any]:
        if path not in on_disk:
            on_disk[path] = load_dataset(path).samples if path.exists() else []
        return on_disk[path]
    lost, notes = 0, []
    refreshed: Counter[Path] = Counter()
    for o in outcomes:
        if o.kind == 'refresh' and o.result is not None and o.result.dataset_path:
            refreshed[Path(o.result.dataset_path)] += o.result.collected
        if o.kind != 'collect':
            continue
        reported = o.result.collected if o.result is not None else o.reported
        if not reported:
            continue
        path = Path(o.result.dataset_path) if o.result is not None and \
            o.result.dataset_path else data / f'{DATASET}.jsonl'
        if not o.motion:
            notes.append(f'a collection of {reported} samples names no motion')
            continue
        found = sum(1 for s in samples(path) if s.motion == o.motion)
        if found < reported:
            lost += reported - found
            notes.append(f'collection {o.motion}: {reported} reported, {found} on disk')
    for path, reported in refreshed.items():
        found = len(samples(path))
        if found < reported:
            lost += reported - found
            notes.append(f'{path.name}: {reported} reported by refreshes, {found} on disk')
    return lost, notes


def payload_reverts(heard: list[tuple[float, float]], declared: list[tuple[float, float]]
                    ) -> int:
    """Changes heard on /payload that no client declared in the 30 s before."""
    return sum(1 for (_, before), (when, kg) in zip(heard, heard[1:]) if kg != before
               and not any(when - 30.0 <= t <= when and k == kg for t, k in declared))


def figures(soak: Soak, watch: Watch, faults: Faults, graph: Graph, clock: dict[str, float],
            stop_codes: dict[str, int | None], fd: dict[str, int]) -> dict[str, Any]:
    ledger, spells = soak.ledger, faults.spells
    outcomes = ledger.outcomes
    moves = [o for o in outcomes if o.kind == 'move' and o.status != 'not_sent']
    goals = {m: sum(1 for o in moves if o.mode == m) for m in MODES}
    succeeded = {m: sum(1 for o in moves if o.mode == m and o.code == 0) for m in MODES}
    unfinished, lost_to_kills, notes = 0, 0, []
    during, other, examples = Counter(), Counter(), {}
    for o in outcomes:
        if o.status == 'lost' and o.kind != 'move' and killed_under(o, spells) is not None:
            lost_to_kills += 1
        elif o.status in ('unfinished', 'lost'):
            unfinished += 1
            if len(notes) < 5:
                notes.append(f'{o.kind} {o.mode} of {o.client}: {o.error[:300]}')
        if o.code not in (0, BUSY[o.kind]):
            key = f'{o.kind} {o.mode} {o.label}'.replace('  ', ' ')
            (during if overlaps(o, spells) else other)[key] += 1
            text = o.result.error_string if o.result is not None else o.error
            examples.setdefault(key, text[:300])
    judged = [o for o in moves if o.code == 0 and o.bound is not None]
    unjudged = sum(1 for o in judged if o.truth_error is None or math.isnan(o.bound))
    false = [o for o in judged if o.truth_error is not None and not math.isnan(o.bound)
             and o.truth_error > o.bound]
    overlap, overlap_notes = concurrency(outcomes, spells)
    lost, lost_notes = lost_samples(outcomes, soak.data)
    for name, code in stop_codes.items():
        if code not in STOP_EXITS:
            watch.crash(name, code, graph.nodes[name].log_tail(30))
    cam = sorted(soak.camera_errors)
    arm_s = clock['end'] - clock['start']
    wall = clock['wall_end'] - clock['wall_start']
    return {
        'goals': {**goals, 'total': sum(goals.values()),
                  'not_sent': sum(1 for o in outcomes if o.status == 'not_sent')},
        'succeeded': succeeded,
        'unfinished_goals': unfinished,
        'false_success': len(false),
        'concurrent_motion': round(overlap, 3),
        'crashes': len(watch.crashes),
        'rss_growth_mb': watch.rss_growth(clock['warm'], clock['end']),
        'rss_mb_series': watch.rss_series(clock['start']),
        'fd_growth': fd,
        'lost_samples': lost,
        'arm_hours': round(arm_s / HOUR, 4),
        'wall_s': round(wall, 1),
        'achieved_rtf': round(arm_s / wall, 2) if wall else None,
        'restarts': {name: node.restarts for name, node in graph.nodes.items()},
        'refused_busy': sum(1 for o in outcomes if o.code == BUSY[o.kind]),
        'lost_to_kills': lost_to_kills,
        'unjudged': unjudged,
        'camera_margin_mm': round(soak.margin * 1e3, 4),
        'camera_error_mm': {'p50': round(cam[len(cam) // 2] * 1e3, 4) if cam else None,
                            'max': round(cam[-1] * 1e3, 4) if cam else None},
        'collections': sum(1 for o in outcomes if o.kind == 'collect'),
        'refreshes': sum(1 for o in outcomes if o.kind == 'refresh'),
        'trainings': dict(ledger.trainings),
        'pairs': dict(ledger.pairs),
        'failures': {'during_faults': dict(during), 'other': dict(other),
                     'examples': examples},
        'faults': {'kills': faults.kills, 'blinds': faults.blinds,
                   'slow_back': faults.slow_back},
        'payload_reverts': payload_reverts(soak.observer.payloads, ledger.payloads),
        'stop_codes': stop_codes,
        'crash_logs': watch.crashes[:5],
        'false_success_examples': [f'{o.mode} to {tuple(round(v, 4) for v in o.target)}: true '
                                   f'error {o.truth_error * 1e3:.3f} mm > bound '
                                   f'{o.bound * 1e3:.3f} mm' for o in false[:5]],
        'concurrent_examples': overlap_notes,
        'unfinished_examples': notes,
        'lost_sample_notes': lost_notes[:5],
        'operator_errors': ledger.errors[:5],
    }


# --- the run ---------------------------------------------------------------------------------
def read_server_settings(soak: Soak, client: FlexarmClient) -> None:
    """The compensator's goal bounds, as it runs them."""
    node = node_name('compensator')
    timeout = liveness.limit(10.0)
    soak.tolerance = client.node_parameter(node, 'position_tolerance', timeout)


def finished(soak: Soak, args: argparse.Namespace, arm_s: float) -> bool:
    return soak.model_ready.is_set() and arm_s >= args.arm_hours * HOUR and all(
        soak.ledger.sent(m) >= args.goals for m in MODES)


def run(args: argparse.Namespace, say: Callable[[str], None]) -> dict[str, Any]:
    wall_start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix='flexarm-soak-') as tmp, \
            reserved_domain(args.domain_id) as domain:
        folder = Path(tmp)
        graph = Graph(domain, folder / 'run', report=say, max_restarts=10**6, parameters={
            node_name('simulator'): {'real_time_factor': args.rtf, **PAYLOAD_ONLY},
            VISION: {'tool_calibration_file': str(folder / 'no_tool_calibration.json'),
                     'camera_calibration_file': str(folder / 'no_camera_calibration.json')},
            LEARNER: {'data_directory': str(folder / 'data'),
                      'model_directory': str(folder / 'models')}})
        graph.start()
        observer = operators = None
        soak = watch = faults = None
        stop_codes: dict[str, int | None] = {}
        clock: dict[str, float] = {}
        try:
            graph.wait_ready(liveness.limit(READY_S))
            observer = Observer(domain)
            soak = Soak(args, observer, folder / 'data')
            watch = Watch(graph, say, args.sample_every)
            faults = Faults(args, watch, observer, soak, say)
            soak.operators = operators = [Operator(i, domain, soak)
                                          for i in range(args.operators)]
            operators[0].client.wait_until_ready(timeout=liveness.limit(60.0))
            read_server_settings(soak, operators[0].client)
            soak.margin = max(2e-5, 3 * observer.camera_error(20, liveness.limit(60.0)))
            say(f'camera margin {soak.margin * 1e3:.4f} mm; tolerance '
                f'{soak.tolerance * 1e3:.3f} mm')
            clock['start'] = clock['warm'] = clock['end'] = observer.clock()
            clock['wall_start'] = time.monotonic()
            for operator in operators:
                operator.thread.start()
            warm, said = False, time.monotonic()
            while True:
                sim = observer.clock()
                watch.check()
                observer.poll()
                watch.sample(sim)
                if not warm and soak.model_ready.is_set():
                    warm = True
                    clock['warm'] = sim
                    watch.warmed(sim)
                    faults.start(sim)
                    say(f'warm at arm time {sim - clock["start"]:.0f} s')
                done = finished(soak, args, sim - clock['start'])
                late = args.max_minutes and time.monotonic() - wall_start > 60 * args.max_minutes
                if warm:
                    faults.step(sim, start_new=not (done or late))
                if (done or late) and not faults.busy():
                    clock['cut_short'] = float(bool(late and not done))
                    break
                if time.monotonic() - said > 30.0:
                    said = time.monotonic()
                    say(f'arm time {sim - clock["start"]:.0f} s: goals sent ' + ', '.join(
                        f'{m} {soak.ledger.sent(m)}' for m in MODES))
                if soak.ledger.errors or not any(o.thread.is_alive() for o in operators):
                    break
                time.sleep(0.5)
            soak.stop.set()
            for operator in operators:
                operator.thread.join(timeout=liveness.limit(MOVE_S + 60.0))
            clock['end'] = observer.clock()
            clock['wall_end'] = time.monotonic()
            time.sleep(5.0)
            watch.check()
            watch.sample(observer.clock(), force=True)
            fd = watch.fd_growth()
            observer.poll()
        finally:
            if faults is not None:
                faults.resume()
            for operator in operators or ():
                operator.close()
            if observer is not None:
                observer.close()
            stop_codes = graph.stop(timeout=10.0)
        if 'wall_end' not in clock:
            raise RuntimeError('the soak did not run to its end (see above)')
        out = figures(soak, watch, faults, graph, clock, stop_codes, fd)
        out['cut_short'] = bool(clock.get('cut_short'))
        return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--arm-hours', type=float, default=2.0, help='[h] of the arm\'s time')
    parser.add_argument('--goals', type=int, default=500, help='fewest goals sent per mode')
    parser.add_argument('--operators', type=int, default=3, help='clients, each in a thread')
    parser.add_argument('--samples', type=int, default=24, help='of the first collection')
    parser.add_argument('--kind', default='rbf', help='predictor kind the operators train')
    parser.add_argument('--payload', type=float, default=2.0, help='[kg] declared now and then')
    parser.add_argument('--kill-every', type=float, default=15.0,
                        help='[min, arm time] between two SIGKILLs (0: none)')
    parser.add_argument('--blind-every', type=float, default=10.0,
                        help='[min, arm time] between two blind spells (0: none)')
    parser.add_argument('--blind-s', type=float, default=45.0,
                        help='[s, arm time] longest blind spell (from 5 s)')
    parser.add_argument('--sample-every', type=float, default=10.0,
                        help='[s, wall] between two process samples of the nodes')
    parser.add_argument('--rtf', type=float, default=10.0, help='simulator real-time factor')
    parser.add_argument('--max-minutes', type=float, default=0.0,
                        help='wall-clock budget, then the run ends early (0: none)')
    smoke = ', '.join(f'--{k.replace("_", "-")} {v:g}' for k, v in SMOKE.items())
    parser.add_argument('--smoke', action='store_true', help=f'smallest run: {smoke}')
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--domain-id', type=int)
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    if args.smoke:
        vars(args).update(SMOKE)
    say = (lambda text: None) if args.json else (lambda text: print(text, flush=True))
    out = run(args, say)
    if not args.json:
        for key in ('crash_logs', 'false_success_examples', 'concurrent_examples',
                    'unfinished_examples', 'lost_sample_notes', 'operator_errors'):
            for line in out[key]:
                print(f'{key}: {line}')
    print(json.dumps(out))


if __name__ == '__main__':
    main()
