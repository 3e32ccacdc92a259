"""``flexarm``: the command line of the flexarm system.

Humans type millimetres and degrees and read them back (every printed pose carries its units);
everything below the CLI is SI, and so is the ``--json`` result. Every outcome is said in
words: results on stdout, anything else (refused, failed, busy, timeout, interrupted) on
stderr as ``flexarm COMMAND: …``; ``--json`` ends stdout with one line of JSON holding the
result and its ``exit_code``. Arguments are checked before anything connects. Whatever takes
more than a moment shows progress on stderr (bars, waiting lines, goal feedback) unless
``--quiet`` or ``--json``. The graph must be running (``flexarm up``) for move/collect/train,
in the same ROS_DOMAIN_ID. DDS stays on this machine (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST,
and transports confined to shared memory and loopback: :mod:`flexarm_bringup.transport`) unless
the environment sets another range or static peers, or ``flexarm up --discovery subnet`` widens
it on purpose.

Exit codes (:class:`flexarm_bringup.outcome_text.Exit`):

    0    success
    1    the server refused the goal or it failed (its result code by name, and a hint)
    2    usage error: bad arguments, refused before connecting
    3    no graph answered within --wait, a server was lost mid-goal, or the goal outlasted
         --timeout (it was cancelled)
    4    busy: another goal or collection runs; try again when it has ended (or end it with
         flexarm cancel)
    5    status: a node of the graph is down, or one reports an ERROR (e.g. a damaged
         calibration file or model record: named, with the reason)
    6    cancel: no goal was running, nothing was cancelled
    130  interrupted (Ctrl-C or SIGTERM): a running goal was cancelled and the command says
         where the arm stopped
"""
from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import signal
import sys
import textwrap
import threading
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from types import FrameType
from typing import Any

from flexarm_bringup import transport
from flexarm_bringup.outcome_text import (
    COLLECT_HINTS,
    EXIT_MEANINGS,
    MOVE_HINTS,
    TRAIN_HINT,
    Exit,
    busy_text,
    code_name,
    failure_text,
    human_units,
    is_busy,
    pose_text,
)
from flexarm_control.execution.modes import MODE_LABELS
from flexarm_core import topics
from flexarm_core.paths import MODELS_DIR, RESULTS_DIR, RUNS_DIR

COMMANDS: dict[str, Callable[[argparse.Namespace], dict[str, Any]]] = {}
UINT32_MAX = 2 ** 32 - 1
MAX_DOMAIN_ID = 232       # the largest ROS_DOMAIN_ID whose DDS ports exist
_GENERATED_MESSAGE = re.compile(r'[/\\](?:msg|srv|action)[/\\]_\w+\.py$')   # rosidl's Python
RIGID_START = 'CLOSED_LOOP started from the rigid solution'   # plan_goal's note: no model
_RESIGNAL = 0.005         # [s] until a signal that came during a message conversion is resent


class Outcome(Exception):
    """A command's outcome other than success: its words, exit code and JSON fields."""

    def __init__(self, text: str, code: Exit, /, **fields: Any) -> None:
        super().__init__(text)
        self.code, self.fields = code, fields


def usage(message: str) -> Outcome:
    """A usage error: bad arguments, found before connecting."""
    return Outcome(message, Exit.USAGE)


def command(func: Callable[[argparse.Namespace], dict[str, Any]]):
    COMMANDS[func.__name__.removeprefix('cmd_')] = func
    return func


def mm(value_m: float) -> float:
    return value_m * 1e3


def deg(value_rad: float) -> float:
    return math.degrees(value_rad)


def pose_dict(pose: Any) -> dict[str, float]:
    """A PlanarPose as a JSON-able dict in SI units."""
    return {'x': pose.x, 'y': pose.y, 'phi': pose.phi}


# --- progress -------------------------------------------------------------------------------
def _progress(args: argparse.Namespace) -> bool:
    return not (args.quiet or args.json)


def _progress_lines(args: argparse.Namespace) -> Callable[[str], None]:
    """``say(text)``: a progress line on stderr, unless --quiet or --json."""
    def say(text: str) -> None:
        if _progress(args):
            print(text, file=sys.stderr, flush=True)
    return say


@contextlib.contextmanager
def _elapsed(what: str, args: argparse.Namespace) -> Iterator[None]:
    """While the block runs: after a second, 'WHAT ... mm:ss' on stderr, counting."""
    if not _progress(args):
        yield
        return
    from tqdm import tqdm

    line = tqdm(desc=what, bar_format='{desc} ... {elapsed}', delay=1.0, leave=False)
    stop = threading.Event()

    def tick() -> None:
        while not stop.wait(0.5):
            line.update(0)

    ticker = threading.Thread(target=tick, daemon=True)
    ticker.start()
    try:
        yield
    finally:
        stop.set()
        ticker.join()
        line.close()


@contextlib.contextmanager
def _steps(what: str, args: argparse.Namespace) -> Iterator[Callable[[int, int, str], None]]:
    """A progress bar on stderr fed by ``progress(done, total, step)`` calls."""
    from tqdm import tqdm

    bars: list[Any] = []      # made by the first call, which knows the total

    def progress(done: int, total: int, step: str) -> None:
        if not bars:
            bars.append(tqdm(desc=what, total=total, unit='step', disable=not _progress(args)))
        bars[0].set_postfix_str(step, refresh=False)
        bars[0].update(done - bars[0].n)

    try:
        yield progress
    finally:
        for bar in bars:
            bar.close()


# --- checks before connecting ---------------------------------------------------------------
def _learner_config() -> dict[str, Any]:
    from flexarm_core.params import load_config

    return load_config('learner.yaml', node_name='flexarm_learner')


def _learner_default(key: str) -> str:
    """The learner's default ``key`` for a help text, read so that the help cannot drift; its
    parameter's name where config/ is not beside the code (an install space without it)."""
    try:
        return str(_learner_config()[key])
    except (OSError, KeyError):
        return f'its {key} parameter'


def _check_region(region: str) -> None:
    presets = _learner_config()['regions']
    if region and region not in presets:
        raise usage(f'unknown region "{region}"; presets of config/learner.yaml: '
                    f'{", ".join(presets)}')


def _check_dataset(name: str) -> None:
    if name:
        from flexarm_control.ros.learner_node import dataset_name_error

        reason = dataset_name_error(name)
        if reason is not None:
            raise usage(reason)


def _check_kind(kind: str) -> None:
    if kind:
        from flexarm_control.learning.predictors import KINDS

        if kind not in KINDS:
            raise usage(f'unknown predictor kind "{kind}"; known kinds: {", ".join(KINDS)}')


def _check_strategy(strategy: str) -> None:
    if strategy:
        from flexarm_control.learning.sampling import STRATEGIES

        if strategy not in STRATEGIES:
            raise usage(f'unknown strategy "{strategy}"; known: {", ".join(STRATEGIES)}')


def _check_bag(path: str) -> None:
    from flexarm_bringup.bag_tools import MCAP_MAGIC, mcap_path

    try:
        file = mcap_path(path)
    except FileNotFoundError as exc:
        raise usage(f'{exc} (a bag is bags/NAME or its .mcap file)') from None
    with open(file, 'rb') as f:
        if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise usage(f'{file} is not an MCAP bag')


# --- the graph --------------------------------------------------------------------------------
@contextlib.contextmanager
def _session(args: argparse.Namespace, learner: bool) -> Iterator[Any]:
    """A client of the graph once its servers answer (a waiting line meanwhile); shut down
    when the block ends."""
    import rclpy

    from flexarm_control.ros.client import init_client

    client = init_client(args.domain_id, args.namespace)
    try:
        domain = client.context.get_domain_id()
        try:
            with _elapsed(f'waiting for the flexarm graph in ROS_DOMAIN_ID={domain}', args):
                client.wait_until_ready(timeout=args.wait, learner=learner)
        except KeyboardInterrupt:
            raise Outcome('interrupted while waiting for the graph; nothing was sent',
                          Exit.INTERRUPTED) from None
        yield client
    finally:
        client.destroy_node()
        rclpy.try_shutdown()


def _full(args: argparse.Namespace, name: str) -> str:
    """The full name of a graph name (:mod:`flexarm_core.topics`) of the arm addressed."""
    return topics.absolute(name, args.namespace)


def _goal(run: Callable[[], Any], server: str, interrupted: Callable[[Any], str]) -> Any:
    """``run()``'s result; busy, lost and interrupted goals as outcomes
    (``interrupted(result)`` words the cancelled goal's result, None if none arrived)."""
    from flexarm_control.ros.client import GoalInterrupted, GoalRejected, ServerLost

    try:
        return run()
    except GoalRejected:
        raise Outcome(busy_text(server), Exit.BUSY) from None
    except ServerLost as exc:
        raise Outcome(str(exc), Exit.NO_GRAPH) from None
    except GoalInterrupted as exc:
        if exc.accepted is False:
            raise Outcome('interrupted; the server had not accepted the goal: nothing moved',
                          Exit.INTERRUPTED) from None
        if exc.accepted is None:
            raise Outcome('interrupted before the server answered whether it accepted the '
                          'goal; if it did, the goal runs on', Exit.INTERRUPTED) from None
        raise Outcome(interrupted(exc.result), Exit.INTERRUPTED) from None


def _no_result() -> str:
    from flexarm_control.ros.client import CANCEL_WAIT

    return f'cancelled; no result from the server within {CANCEL_WAIT:.0f} s'


# --- move -------------------------------------------------------------------------------------
def _measured_text(pose: Any, position_error: float, angle_error: float) -> str:
    return (f'measured {pose_text((pose.x, pose.y, pose.phi))}; error '
            f'{mm(position_error):.3f} mm, {deg(angle_error):.4f} deg')


def _show_feedback(fb: Any) -> None:
    """A goal's feedback line: progress, so on stderr (stdout holds the result only)."""
    measured = (' ' + _measured_text(fb.measured_pose, fb.position_error, fb.angle_error)
                if fb.measured else '')
    print(f'  [{fb.iteration}] {fb.phase}{measured}', file=sys.stderr, flush=True)


def _is_rigid(result: Any) -> bool:
    """Whether a successful MoveToPose result is of a RIGID goal. The result does not carry
    the mode. Only RIGID and CLOSED_LOOP without a model to trust plan with neither a model
    (``model_version`` '') nor compensation steps; that CLOSED_LOOP goal notes ``RIGID_START``
    in ``error_string`` (:func:`flexarm_control.execution.planning.plan_goal`) and may make
    corrective moves, where RIGID makes one."""
    return (not result.model_version and result.compensation_iterations == 0
            and result.iterations <= 1 and RIGID_START not in result.error_string)


def _move_text(result: Any) -> str:
    """A MoveToPose result in words: reached (how well), refused or failed (why). A RIGID
    goal only 'moved (uncompensated)': it makes no promise of accuracy to reach."""
    from flexarm_msgs.action import MoveToPose

    if result.error_code != MoveToPose.Result.SUCCESSFUL:
        return failure_text(code_name(MoveToPose.Result, result.error_code),
                            result.error_string, MOVE_HINTS, moved=result.iterations > 0)
    if result.iterations == 0:                  # a dry run: the plan, nothing moved
        return _plan_text(result)
    rigid = _is_rigid(result)
    verb = 'moved (uncompensated)' if rigid else 'reached' if result.measured else 'moved'
    reached = f'{verb} in {result.iterations} move(s)' + (': ' + _measured_text(
        result.measured_pose, result.position_error, result.angle_error) if result.measured
        else ', not measured') + ('' if rigid else f' ({_model_text(result.model_version)})')
    learned = (_learned_text(result.data_distance, result.prediction_std)
               if result.data_distance or result.prediction_std else '')
    notes = f'; {human_units(result.error_string)}' if result.error_string else ''
    return reached + learned + notes


def _model_text(version: str) -> str:
    return f'model v{version}' if version else 'rigid plan, no model'


def _learned_text(distance: float, std: float) -> str:
    """How far from the learned data a plan lies; the model's std only where it has one
    (GP: > 0; kinds without a posterior give 0, which is no claim of certainty)."""
    return (f'; {distance:.2f} sample spacings from the learned data'
            + (f', model std {mm(std):.3f} mm' if std > 0 else ''))


def _plan_text(result: Any) -> str:
    """A dry run's plan: what would be commanded, and from which model."""
    q, d, c = result.joint_positions, result.predicted_deflection, result.commanded_pose
    learned = (_learned_text(result.data_distance, result.prediction_std)
               if result.model_version else '')
    notes = human_units(result.error_string.replace('dry run: nothing moved', '').strip('; '))
    return (f'plan ({_model_text(result.model_version)}; nothing moved): command '
            f'{pose_text((c.x, c.y, c.phi))} to the rigid model, joints {deg(q[0]):.3f} deg, '
            f'{mm(q[1]):.2f} mm, {deg(q[2]):.3f} deg, {deg(q[3]):.3f} deg; predicted '
            f'deflection {mm(d.x):.3f} mm, {mm(d.y):.3f} mm, {deg(d.phi):.4f} deg'
            + learned + (f'; {notes}' if notes else ''))


def _move_interrupted(result: Any) -> str:
    """Where a cancelled goal left the arm: the rigid pose of the joints it stopped at."""
    import numpy as np

    from flexarm_core.kinematics import ArmGeometry, forward
    from flexarm_core.params import load_config
    from flexarm_msgs.action import MoveToPose

    if result is None:
        return f'{_no_result()}: where the arm stopped is unknown'
    if result.error_code != MoveToPose.Result.CANCELED:
        return f'interrupted after the goal had ended: {_move_text(result)}'
    geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
    pose = forward(geometry, np.array(result.joint_positions))
    return f'cancelled; arm stopped at {pose_text(pose)} (rigid kinematics of its joints)'


@command
def cmd_move(args: argparse.Namespace) -> dict[str, Any]:
    """Move the tip to X Y PHI [mm mm deg]."""
    from flexarm_msgs.action import MoveToPose

    feedback = _show_feedback if _progress(args) else None
    with _session(args, learner=False) as client:
        result = _goal(lambda: client.move_to(
            args.x / 1e3, args.y / 1e3, math.radians(args.phi), mode=args.mode,
            position_tolerance=args.position_tolerance / 1e3,
            angle_tolerance=math.radians(args.angle_tolerance),
            max_corrections=args.max_corrections, trial=args.trial, timeout=args.timeout,
            allow_extrapolation=args.allow_extrapolation, dry_run=args.dry_run,
            feedback=feedback),
            _full(args, topics.MOVE_TO_POSE), _move_interrupted)
    out = {'ok': result.error_code == MoveToPose.Result.SUCCESSFUL,
           'error_code': result.error_code,
           'error_name': code_name(MoveToPose.Result, result.error_code),
           'error_string': result.error_string, 'mode': args.mode,
           'target': {'x': args.x / 1e3, 'y': args.y / 1e3, 'phi': math.radians(args.phi)},
           'joint_positions': list(result.joint_positions),
           'commanded_pose': pose_dict(result.commanded_pose),
           'predicted_deflection': pose_dict(result.predicted_deflection),
           'measured': result.measured, 'measured_pose': pose_dict(result.measured_pose),
           'position_error': result.position_error, 'angle_error': result.angle_error,
           'iterations': result.iterations,
           'compensation_iterations': result.compensation_iterations,
           'data_distance': result.data_distance, 'prediction_std': result.prediction_std,
           'model_version': result.model_version, 'dry_run': args.dry_run}
    if not out['ok']:
        if is_busy(result.error_string):      # lost the race of two goals sent together
            raise Outcome(busy_text(_full(args, topics.MOVE_TO_POSE)), Exit.BUSY, **out)
        raise Outcome(_move_text(result), Exit.FAILED, **out)
    print(_move_text(result))
    return out


# --- learner ----------------------------------------------------------------------------------
def _collect_kept(result: Any) -> str:
    return (f'{result.collected} collected, {result.skipped} skipped; {result.total} samples '
            f'in {result.dataset_path}')


def _collect_interrupted(result: Any) -> str:
    from flexarm_msgs.action import CollectSamples

    if result is None:
        return f'{_no_result()}; the samples collected before are kept in the dataset'
    if result.error_code != CollectSamples.Result.CANCELED:
        return f'interrupted after the collection had ended: {_collect_kept(result)}'
    return f'cancelled; the samples collected are kept: {_collect_kept(result)}'


@command
def cmd_collect(args: argparse.Namespace) -> dict[str, Any]:
    """Collect N deflection samples with the learner."""
    max_count = _learner_config()['max_count']
    if args.count > max_count:
        raise usage(f'count must be 1..{max_count} (max_count of config/learner.yaml), '
                    f'got {args.count}')
    _check_region(args.region)
    _check_strategy(args.strategy)
    _check_dataset(args.dataset)
    from tqdm import tqdm

    from flexarm_msgs.action import CollectSamples

    with _session(args, learner=True) as client:
        if args.payload is not None:
            client.set_payload(args.payload)
            print(f'payload declared: {args.payload:g} kg')
        bar = tqdm(total=args.count, unit='sample', desc='collect', disable=not _progress(args))
        try:
            result = _goal(lambda: client.collect(
                args.count, region=args.region, strategy=args.strategy, seed=args.seed,
                dataset=args.dataset, timeout=args.timeout,
                feedback=lambda fb: bar.update(fb.k - bar.n)),
                _full(args, topics.COLLECT_SAMPLES), _collect_interrupted)
        finally:
            bar.close()
    name = code_name(CollectSamples.Result, result.error_code)
    out = {'ok': result.error_code == CollectSamples.Result.SUCCESSFUL,
           'error_code': result.error_code, 'error_name': name,
           'error_string': result.error_string, 'collected': result.collected,
           'skipped': result.skipped, 'total': result.total,
           'dataset_path': result.dataset_path}
    if out['ok']:
        print(_collect_kept(result) + (
            f' ({human_units(result.error_string)})' if result.error_string else ''))
        return out
    if is_busy(result.error_string):
        raise Outcome(busy_text(_full(args, topics.COLLECT_SAMPLES)), Exit.BUSY, **out)
    moved = name != 'INVALID_GOAL'
    raise Outcome(failure_text(name, result.error_string, COLLECT_HINTS, moved) + (
        f'\n  dataset: {_collect_kept(result)}' if moved else ''), Exit.FAILED, **out)


@command
def cmd_refresh(args: argparse.Namespace) -> dict[str, Any]:
    """Mend a model the health check reports stale from a few new samples."""
    if args.region:
        _check_region(args.region)
    from tqdm import tqdm

    from flexarm_msgs.action import RefreshModel

    with _session(args, learner=True) as client:
        bar = tqdm(unit='sample', desc='refresh', disable=not _progress(args))

        def show(fb: Any) -> None:
            bar.total = fb.n
            bar.update(fb.k - bar.n)

        try:
            result = _goal(lambda: client.refresh(args.count, args.region, args.timeout, show,
                                                  args.force),
                           _full(args, topics.REFRESH_MODEL),
                           lambda r: 'interrupted; the model is unchanged unless the refresh '
                                     'had ended')
        finally:
            bar.close()
    name = code_name(RefreshModel.Result, result.error_code)
    out = {'ok': result.error_code == RefreshModel.Result.SUCCESSFUL,
           'error_code': result.error_code, 'error_name': name,
           'error_string': result.error_string, 'collected': result.collected,
           'dataset_path': result.dataset_path, 'model_version': result.model.version,
           'residual_before': result.residual_before, 'residual_after': result.residual_after}
    if not out['ok']:
        if is_busy(result.error_string):
            raise Outcome(busy_text(_full(args, topics.REFRESH_MODEL)), Exit.BUSY, **out)
        raise Outcome(f'{name}: {human_units(result.error_string)}', Exit.FAILED, **out)
    print(f'model v{result.model.version} announced: the previous one corrected from '
          f'{result.collected} new samples (in {result.dataset_path}); their median residual '
          f'{mm(result.residual_before):.3f} mm before, {mm(result.residual_after):.3f} mm '
          'after')
    return out


def _cancelled_text(goal: Any) -> str:
    """What ``flexarm cancel`` ended: the goal, who sent it and what its result says."""
    who = (f'sent by {goal.sender}' if goal.sender else
           'its server does not record who sent it; clients of the action now: '
           + (', '.join(goal.clients) or 'none'))
    if goal.result is None:
        text = _no_result()
    else:
        words = {topics.MOVE_TO_POSE: _move_interrupted, topics.COLLECT_SAMPLES:
                 _collect_interrupted, topics.REFRESH_MODEL: lambda r: 'cancelled; the model '
                 'is unchanged'}
        name = next(n for n in words if goal.action.endswith('/' + n))
        text = words[name](goal.result.result)
    return f'{goal.action} goal {goal.goal_id[:8]} ({who}): {text}'


@command
def cmd_cancel(args: argparse.Namespace) -> dict[str, Any]:
    """Cancel whatever goal runs on the arm (move, collect, refresh), whoever sent it."""
    with _session(args, learner=False) as client:
        with _elapsed('cancelling', args):
            goals = client.cancel_all(timeout=args.wait)
    rows = [{'action': g.action, 'goal_id': g.goal_id, 'sender': g.sender,
             'clients': g.clients, 'error_code': None if g.result is None else
             g.result.result.error_code, 'error_string': None if g.result is None else
             g.result.result.error_string} for g in goals]
    if not goals:
        raise Outcome('nothing to cancel: no goal runs on '
                      f'{_full(args, topics.MOVE_TO_POSE)} or the learner', Exit.NOTHING_TO_CANCEL,
                      cancelled=rows)
    for goal in goals:
        print(_cancelled_text(goal))
    return {'ok': True, 'cancelled': rows}


@command
def cmd_payload(args: argparse.Namespace) -> dict[str, Any]:
    """Show the payload the arm carries, or declare a new one [kg] (a tool picked up)."""
    with _session(args, learner=True) as client:
        if args.kg is not None:
            client.set_payload(args.kg)
        kg = float(client.node_parameter('flexarm_learner', 'payload'))
    print(f'payload: {kg:g} kg' + (' (declared now)' if args.kg is not None else ''))
    return {'ok': True, 'payload_kg': kg}


@command
def cmd_train(args: argparse.Namespace) -> dict[str, Any]:
    """Train a deflection predictor on a dataset; prints the validation metrics."""
    _check_kind(args.kind)
    _check_dataset(args.dataset)
    what = f'training {args.kind or "the default kind"} on dataset {args.dataset or "default"}'
    with _session(args, learner=True) as client:
        try:
            with _elapsed(what, args):
                response = client.train(args.kind, args.settings, dataset=args.dataset,
                                        timeout=args.timeout)
        except KeyboardInterrupt:
            raise Outcome('interrupted; the learner finishes this training anyway (training '
                          'cannot be cancelled) and announces its model if it succeeds',
                          Exit.INTERRUPTED) from None
    m = response.metrics
    out = {'ok': response.success, 'message': response.message,
           'model_version': response.model_version, 'model_path': response.model_path,
           'metrics': {k: getattr(m, k) for k in (
               'validation', 'samples', 'max_error_x', 'max_error_y', 'max_error_phi',
               'mean_error_x', 'mean_error_y', 'mean_error_phi', 'selected_settings',
               'max_slope')} | {'excluded_samples': list(m.excluded_samples)}}
    if not response.success:
        if is_busy(response.message):
            raise Outcome(response.message, Exit.BUSY, **out)
        raise Outcome(f'{human_units(response.message)}\n  what to do: {TRAIN_HINT}',
                      Exit.FAILED, **out)
    print(f'model v{response.model_version} at {response.model_path} '
          f'(chosen by validation: {m.selected_settings})\n'
          f'{m.validation}, {m.samples} samples: max |error| x {mm(m.max_error_x):.3f} mm, '
          f'y {mm(m.max_error_y):.3f} mm, phi {deg(m.max_error_phi):.4f} deg; mean '
          f'{mm(m.mean_error_x):.3f} mm, {mm(m.mean_error_y):.3f} mm, '
          f'{deg(m.mean_error_phi):.4f} deg')
    if len(m.excluded_samples):
        print(f'excluded as outliers: {len(m.excluded_samples)} sample(s), dataset '
              f'indices {list(m.excluded_samples)}')
    if response.message:
        print(human_units(response.message))
    return out


# --- graph and experiments --------------------------------------------------------------------
@command
def cmd_up(args: argparse.Namespace) -> dict[str, Any]:
    """Start the graph (one process per node), wait until ready, supervise until stopped."""
    import time

    from flexarm_bringup.experiment import reserved_domain
    from flexarm_bringup.graph_status import FirstReports, GraphWatch
    from flexarm_bringup.supervisor import Graph
    from flexarm_core import liveness

    if args.link_key and not os.path.isfile(args.link_key):
        raise usage(f'no key file {args.link_key} (make one with flexarm keygen FILE)')
    name = args.name or time.strftime('up-%Y%m%d-%H%M%S') + (
        f'-{args.namespace.replace("/", "-")}' if args.namespace else '')
    simulated = {'real_time_factor': args.rtf, **_world(args)}
    link = {'link_key_file': os.path.abspath(args.link_key)} if args.link_key else {}
    params: dict[str, dict[str, Any]] = {'flexarm_sim': simulated,
                                         'flexarm_fake_controller': simulated | link,
                                         'flexarm_bridge': link}
    if args.record:
        params['flexarm_recorder'] = {'bag_name': args.record,
                                      'record_images': args.record_images}
    if args.foxglove:
        params['flexarm_foxglove'] = {'port': args.foxglove}
    optional = (('flexarm_recorder',) if args.record else ()) + (
        ('flexarm_foxglove',) if args.foxglove is not None else ())
    discovery = args.discovery.upper()
    # up's own participants (the readiness checks) share its nodes' range and transports
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = discovery
    transport.apply(os.environ)
    exposure = transport.warning(os.environ)
    if exposure:
        print(exposure, flush=True)
    with reserved_domain(args.domain_id) as domain:
        try:
            graph = Graph(domain, RUNS_DIR / name, robot=args.robot, parameters=params,
                          optional=optional, discovery=discovery, namespace=args.namespace,
                          only=args.only)
        except ValueError as exc:
            raise usage(str(exc)) from None
        started, ready = time.monotonic(), None
        print(f'starting {", ".join(graph.nodes)} in ROS_DOMAIN_ID={domain}; logs in '
              f'{graph.run_dir}', flush=True)
        if graph.remote:
            print(_remote_text(graph.remote, discovery), flush=True)
        reports = FirstReports(lambda: GraphWatch(domain, args.namespace),
                               lambda line: print(line, flush=True))
        hangup = _bind_lifetime(args.outlive_parent)
        try:
            graph.start()
            graph.wait_ready(args.timeout)
            ready = time.monotonic() - started
            arm = f' --namespace {args.namespace}' if args.namespace else ''
            print(f'graph ready in {ready:.1f} s. In another shell: ROS_DOMAIN_ID={domain} '
                  f'flexarm move 1450 -150 -45{arm}. Ctrl-C stops '
                  f'{"the nodes of this host" if graph.remote else "everything"}'
                  f'{"" if args.outlive_parent else LIFETIME_TEXT}.', flush=True)
            watch = reports.expect(graph.nodes, liveness.limit(REPORT_WAIT))
            print(_starting_model(watch), flush=True)
            if 'flexarm_vision' in graph.nodes:
                print(_calibration(watch), flush=True)
            if args.foxglove is not None:
                print(_foxglove_text(args.foxglove), flush=True)
            while True:     # what goes wrong: a death, an ERROR in a (re)started node's reports
                reports.step(0.5)
                restarted = [n for n in graph.check() if not graph.nodes[n].reported]
                if restarted:
                    reports.expect(restarted, liveness.limit(RESTART_REPORT_WAIT))
        except KeyboardInterrupt:
            pass
        finally:
            reports.close()
            codes = graph.stop()
            if hangup:
                signal.signal(signal.SIGHUP, signal.SIG_DFL)
            print('stopped: ' + ', '.join(f'{n} ({c})' for n, c in codes.items()), flush=True)
    return {'ok': True, 'domain_id': domain, 'exit_codes': codes, 'run_dir': str(graph.run_dir)}


LIFETIME_TEXT = ', and so does the end of the process that started this one (--outlive-parent)'
# [s, wall; liveness-scaled] for the first /diagnostics report of a node of a ready graph, of a
# restarted one (it imports, starts and is discovered first)
REPORT_WAIT = 5.0
RESTART_REPORT_WAIT = 20.0


def _bind_lifetime(outlive_parent: bool) -> bool:
    """Tie ``up`` (and so its graph) to what started it, unless ``outlive_parent``: the kernel
    sends SIGTERM when the starting process (thread) ends, a harness killed at its time budget
    included, and SIGTERM stops the graph as Ctrl-C does. Under init or a service manager that
    changes nothing (the parent outlives the service). A hang-up (the terminal closed) stops it
    too, unless ignored (``nohup``). Whether SIGHUP's handler was set (to undo at the end)."""
    from flexarm_core.parent_death import signal_on_parent_death

    signal_on_parent_death(0 if outlive_parent else signal.SIGTERM)
    if signal.getsignal(signal.SIGHUP) != signal.SIG_DFL:
        return False
    signal.signal(signal.SIGHUP, _interrupt)   # the default ends the process without a stop
    return True


def _remote_text(remote: tuple[str, ...], discovery: str) -> str:
    """What `up --only` expects from the other hosts, and whether DDS can reach them."""
    text = f'the rest of the graph must run on other hosts: {", ".join(remote)}'
    if not transport.exposed(os.environ | {transport.RANGE_ENV: discovery}):
        text += ('; but DDS discovery stays on this machine: use --discovery subnet or set '
                 'ROS_STATIC_PEERS to the other hosts')
    return text


def _foxglove_text(port: int) -> str:
    """Where Foxglove connects (``port`` 0: config/foxglove.yaml's) and which layout."""
    from flexarm_core.params import config_path, load_config

    config = load_config('foxglove.yaml', node_name='flexarm_foxglove')
    return (f'Foxglove: open a connection to ws://{config["host"]}:{port or config["port"]} '
            f'(Foxglove WebSocket) and import the layout {config_path("foxglove_layout.json")}')


def _starting_model(watch: Any, listen: float = 3.0) -> str:
    """Which model the compensator of a just-started graph runs (it loads the learner's
    current one within a moment of start-up), or why there is none."""
    from flexarm_bringup.graph_status import model_summary, starting_model_text
    from flexarm_core import liveness

    def learner() -> Any:
        return watch.statuses.get('flexarm_learner: model')

    watch.spin(liveness.limit(listen), until=lambda: watch.active_model is not None
               or starting_model_text(None, learner()) is not None)
    return (starting_model_text(model_summary(watch.active_model), learner())
            or 'model driving the arm: none yet (the compensator has loaded none so far)')


def _calibration(watch: Any, listen: float = 3.0) -> str:
    """Whether the camera of a just-started graph is calibrated (its vision node's first
    report)."""
    from flexarm_bringup.graph_status import CALIBRATION_STATUS, calibration_text
    from flexarm_core import liveness

    watch.spin(liveness.limit(listen), until=lambda: CALIBRATION_STATUS in watch.statuses)
    return calibration_text(watch.statuses.get(CALIBRATION_STATUS))


def _interrupt(signum: int, frame: FrameType | None) -> None:
    """SIGINT/SIGTERM: raise KeyboardInterrupt, so that a running goal is cancelled.

    Never while rclpy converts a ROS message (Python code of a generated message module
    called from its C++ layer): there pybind11 would turn the exception into a RuntimeError
    ('Unable to convert call argument') and the goal would run on. The signal is sent again
    ``_RESIGNAL`` later instead (a conversion takes microseconds)."""
    while frame is not None:
        if _GENERATED_MESSAGE.search(frame.f_code.co_filename):
            threading.Timer(_RESIGNAL, os.kill, (os.getpid(), signum)).start()
            return
        frame = frame.f_back
    raise KeyboardInterrupt


@command
def cmd_ps(args: argparse.Namespace) -> dict[str, Any]:
    """List the flexarm graphs running on this machine: domain, namespace, supervisor, robot."""
    from flexarm_bringup import supervisor
    from flexarm_bringup.running_graphs import graph_table, running_graphs

    graphs = running_graphs(supervisor.LOCK_DIR, RUNS_DIR)
    print(graph_table(graphs) if graphs else 'no flexarm graph runs on this machine')
    return {'ok': True, 'graphs': [g.as_dict() for g in graphs]}


@command
def cmd_down(args: argparse.Namespace) -> dict[str, Any]:
    """Stop a graph of this machine (as Ctrl-C in its shell) and wait until it has ended."""
    from flexarm_bringup import supervisor
    from flexarm_bringup.running_graphs import (
        AmbiguousGraph,
        NoSuchGraph,
        running_graphs,
        select,
        stop,
    )

    try:
        graph = select(running_graphs(supervisor.LOCK_DIR, RUNS_DIR), args.domain_id,
                       args.namespace)
    except NoSuchGraph as exc:
        raise Outcome(str(exc), Exit.NO_GRAPH) from None
    except AmbiguousGraph as exc:
        raise usage(str(exc)) from None
    what = f'the graph in ROS domain {graph.domain_id}' + (
        f' with namespace {graph.namespace}' if graph.namespace else '')
    with _elapsed(f'stopping {what} (supervisor pid {graph.supervisor_pid})', args):
        ended = stop(graph, args.timeout)
    fields = {'graph': graph.as_dict()}
    if not ended:
        raise Outcome(f'{what} is still stopping after {args.timeout:g} s (supervisor pid '
                      f'{graph.supervisor_pid}); see flexarm ps', Exit.FAILED, **fields)
    print(f'stopped {what} (supervisor pid {graph.supervisor_pid})')
    return {'ok': True, **fields}


def _experiment(args: argparse.Namespace, **overrides: Any) -> dict[str, Any]:
    import time

    from flexarm_bringup.experiment import (
        ExperimentSettings,
        reserved_domain,
        run_experiment,
        table_text,
    )

    _check_kind(args.kind)
    settings = ExperimentSettings(
        name=args.name or time.strftime(f'{args.command}-%Y%m%d-%H%M%S'),
        samples=args.samples, kind=args.kind, real_time_factor=args.rtf,
        record=not args.no_record, seed=args.seed, world=_world(args), **overrides)
    with reserved_domain(args.domain_id) as domain:
        summary = run_experiment(settings, domain, progress=_progress(args))
    print(table_text(summary))
    print(f'results in {summary["results"]}' + (
        f', bag in {summary["bag"]}' if summary['bag'] else '') +
        f'; {summary["seconds"]:.0f} s in all')
    out = {k: v for k, v in summary.items() if k != 'trials'}
    out['ok'] = not summary['nodes_died']
    if not out['ok']:
        raise Outcome(f'node(s) died during the run: {", ".join(summary["nodes_died"])} (their '
                      f'logs are in runs/{settings.name}/)', Exit.FAILED, **out)
    return out


@command
def cmd_demo(args: argparse.Namespace) -> dict[str, Any]:
    """Collect, train and run the paper's Table 10 targets in all three modes."""
    return _experiment(args)


@command
def cmd_benchmark(args: argparse.Namespace) -> dict[str, Any]:
    """Tables 9 and 10 plus held-out random targets, side by side with the paper."""
    return _experiment(args, random_targets=args.random, table9=True)


@command
def cmd_study(args: argparse.Namespace) -> dict[str, Any]:
    """Tables 7 and 8 sensitivity study on the simulator (offline, no graph needed)."""
    _check_region(args.region)
    from flexarm_bringup.study import QUICK, run_study, table_text, write_study

    overrides = {'region': args.region, 'seeds': args.seeds} | (QUICK if args.quick else {})
    with _steps('study', args) as progress:
        result = run_study(overrides, progress)
    paths = write_study(result, Path(args.out) / args.region)
    print(table_text(result))
    print(f"written: {', '.join(str(p) for p in paths.values())} "
          f"({result['elapsed_s']:.0f} s)")
    return {'ok': True, **result, **{k: str(v) for k, v in paths.items()}}


# --- files ------------------------------------------------------------------------------------
@command
def cmd_bag(args: argparse.Namespace) -> dict[str, Any]:
    """Inspect a recorded bag (info) or export its trials and figures as CSV + PNG (export)."""
    _check_bag(args.path)
    from mcap.exceptions import McapError

    from flexarm_bringup.bag_tools import bag_info, export_figures, export_trials, format_bag_info

    say = _progress_lines(args)
    try:
        if args.action == 'info':
            info = bag_info(args.path, say)
            print(format_bag_info(info))
            return {'ok': True, **info}
        out_dir = args.out or str(args.path).rstrip('/')
        csv_path, png_path = export_trials(args.path, out_dir, args.namespace, say)
        files = export_figures(args.path, out_dir, args.namespace, say)
    except McapError as exc:
        raise Outcome(f'{args.path} is damaged: {exc}', Exit.FAILED) from None
    print(f'trials: {csv_path}\nplot:   {png_path}' + ''.join(f'\nfile:   {p}' for p in files))
    return {'ok': True, 'csv': str(csv_path), 'png': str(png_path),
            'files': [str(p) for p in files]}


@command
def cmd_status(args: argparse.Namespace) -> dict[str, Any]:
    """What runs in the domain, which model drives the arm, and what is wrong (exit 5)."""
    import rclpy

    from flexarm_bringup.graph_status import (
        graph_problems,
        query,
        status_text,
        supervisor_record,
    )
    from flexarm_control.ros.client import init_client

    client = init_client(args.domain_id, args.namespace)
    try:
        record = supervisor_record(RUNS_DIR, client.context.get_domain_id(), args.namespace)
        with _elapsed('asking the graph', args):
            status = query(client, args.namespace, record)
    finally:
        client.destroy_node()
        rclpy.try_shutdown()
    silent = status['controller'] if not status['joint_state_rate_hz'] else None
    status['problems'] = graph_problems(status['errors'], record, silent_controller=silent)
    print(status_text(status, record))
    status['supervisor'] = record
    if not any(status['nodes'].values()):
        where = f'ROS_DOMAIN_ID={status["domain_id"]}'
        if status['arms']:      # arms under other namespaces
            arms = ', '.join(arm or '(no namespace)' for arm in status['arms'])
            arm = f'under /{args.namespace}' if args.namespace else 'without namespace'
            raise Outcome(f'no flexarm graph in {where} {arm}; the domain runs the arm(s) '
                          f'{arms}: pass --namespace NS', Exit.NO_GRAPH, **status)
        raise Outcome(f'no flexarm graph in {where}: start one with `flexarm up`, or pass '
                      '--domain-id', Exit.NO_GRAPH, **status)
    if status['problems']:
        raise Outcome(f'the graph has {len(status["problems"])} problem(s): see PROBLEMS above',
                      Exit.DEGRADED, **status)
    return {'ok': True, **status}


@command
def cmd_model(args: argparse.Namespace) -> dict[str, Any]:
    """List the trained models (list) or make an earlier one current again (use VERSION)."""
    return _model_list(args) if args.action == 'list' else _model_use(args)


def _model_list(args: argparse.Namespace) -> dict[str, Any]:
    from flexarm_bringup.graph_status import file_summary, model_line
    from flexarm_control.learning.model_store import list_models
    from flexarm_control.learning.predictors.base import read_model

    directory = Path(args.models) if args.models else MODELS_DIR / args.namespace
    entries = list_models(directory, lambda path: read_model(path)[0])
    if not entries:
        print(f'no models in {directory}: collect samples and `flexarm train`')
    rows = []
    for entry in entries:
        mark = '*' if entry.current else ' '
        if entry.metadata is None:
            print(f'{mark} v{entry.version}: unusable: {human_units(entry.problem)}')
            rows.append({'version': str(entry.version), 'current': entry.current,
                         'path': str(entry.path), 'problem': entry.problem})
            continue
        summary = file_summary(str(entry.version), entry.path, entry.metadata)
        print(mark + ' ' + model_line(entry.path.name, summary))
        rows.append(summary | {'current': entry.current})
    if entries:
        print("* = current (announced by the learner; `flexarm status` shows what the "
              "compensator runs)")
    return {'ok': True, 'models': rows}


def _model_use(args: argparse.Namespace) -> dict[str, Any]:
    from flexarm_bringup.graph_status import model_line, model_summary

    if not args.version.isdecimal():
        raise usage('model use needs a version number (see flexarm model list), not '
                    f'{args.version!r}')
    with _session(args, learner=True) as client:
        response = client.use_model(args.version, timeout=args.wait)
        if not response.success:
            raise Outcome(response.message, Exit.FAILED)
        with _elapsed(f'waiting for the compensator to load v{args.version}', args):
            client.wait_for_model(response.model.version, timeout=args.wait)
    summary = model_summary(response.model)
    print(model_line('model driving the arm now', summary))
    return {'ok': True, 'model': summary}


@command
def cmd_calibrate(args: argparse.Namespace) -> dict[str, Any]:
    """Measure the camera's error in the tool frame against a reference; correct for it. With
    --camera, first the camera's own parameters that the plate shows."""
    from flexarm_bringup.calibration import calibrate_lens, calibrate_tool
    from flexarm_core.paths import CALIBRATION_DIR

    folder = CALIBRATION_DIR / args.namespace
    path = Path(args.file) if args.file else folder / 'tool_camera.json'
    say = _progress_lines(args)
    out: dict[str, Any] = {'ok': True}
    with _session(args, learner=False) as client:
        if args.camera:
            camera_path = Path(args.camera_file) if args.camera_file else folder / 'camera.json'
            change, lens, lens_details = calibrate_lens(client, camera_path, args.timeout, say)
            print(f'camera: {change.describe()} (from {lens.views} images, '
                  f'{lens.holes} holes; reprojection {lens.rms_before_px:.3f} px -> '
                  f'{lens.rms_after_px:.3f} px); stored in {camera_path}, the vision node '
                  f'measures through it from now on.\n  determined: {lens.determined}\n  not '
                  f'determined from the plate: {lens.not_determined}', flush=True)
            out.update(camera_correction=change.as_list(), camera_path=str(camera_path),
                       camera=lens_details)
        c, found, details = calibrate_tool(client, args.reference_topic, path, args.timeout,
                                           say)
    print(f'camera error in the tool frame: axial {mm(c.axial):.4f} mm, lateral '
          f'{mm(c.lateral):.4f} mm, angle {deg(c.angle):.5f} deg ({found.poses} poses; largest '
          f'deviation of one pose {mm(found.spread[0]):.4f} mm, {deg(found.spread[1]):.5f} '
          f'deg); stored in {path}, the vision node corrects for it from now on')
    return {**out, 'tool_correction': c.as_list(), 'path': str(path), **details}


@command
def cmd_keygen(args: argparse.Namespace) -> dict[str, Any]:
    """Write a new site key for the controller link (give it to the PC and the controller)."""
    from flexarm_bridge.link_auth import make_key

    if os.path.exists(args.path):
        raise ValueError(f'{args.path} exists; a new key would lock out whoever uses it')
    path = make_key(args.path)
    print(f'site key written to {path} (mode 600). Use it on both ends: '
          f'flexarm up --robot bridge --link-key {path}, and the controller\'s configuration')
    return {'ok': True, 'path': str(path)}


# --- arguments --------------------------------------------------------------------------------
class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter,
                     argparse.RawDescriptionHelpFormatter):
    """Shows each option's default, unless it is empty or its help says what it is."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        default = action.default
        if (default is None or default is False or default == '' or default == {}
                or '(default' in (action.help or '')):
            return action.help
        return super()._get_help_string(action)


def _checked(convert: Callable[[str], Any], ok: Callable[[Any], bool],
             rule: str) -> Callable[[str], Any]:
    """An argparse type: ``convert(text)`` if that works and the value is ``ok``."""
    def parse(text: str) -> Any:
        try:
            value = convert(text)
        except ValueError:
            value = None
        if value is None or not ok(value):
            raise argparse.ArgumentTypeError(f'must be {rule}, got {text!r}')
        return value
    return parse


def _json_object(text: str) -> dict[str, Any]:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f'not valid JSON ({exc}): {text!r}') from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f'must be a JSON object, e.g. \'{{"hidden": [10]}}\', '
                                         f'got {text!r}')
    return value


_positive_int = _checked(int, lambda v: 0 < v <= UINT32_MAX, 'a whole number > 0')
_natural = _checked(int, lambda v: 0 <= v <= UINT32_MAX, 'a whole number >= 0')
_domain = _checked(int, lambda v: 0 <= v <= MAX_DOMAIN_ID, f'a ROS domain 0..{MAX_DOMAIN_ID}')
_port = _checked(int, lambda v: 0 < v < 2 ** 16, 'a TCP port 1..65535')
_finite = _checked(float, math.isfinite, 'a finite number')
_non_negative = _checked(float, lambda v: math.isfinite(v) and v >= 0, 'a number >= 0')
_positive = _checked(float, lambda v: math.isfinite(v) and v > 0, 'a number > 0')


def _output_options(parser: argparse.ArgumentParser, default: Any) -> None:
    """--json and --quiet, accepted before and after the subcommand."""
    parser.add_argument('--json', action='store_true', default=default,
                        help='end the output with one line of JSON holding the result '
                             '(SI units; implies --quiet)')
    parser.add_argument('--quiet', action='store_true', default=default,
                        help='no progress output (bars, waiting lines, goal feedback)')


def _graph_options(parser: argparse.ArgumentParser, graph: str) -> None:
    """--domain-id: of the graph a command starts ('start': a free one by default) or of the
    running graph it talks to ('running', 'wait': the environment's, as rclpy takes it); and
    --wait for the servers of the commands that send them requests ('wait')."""
    parser.add_argument('--domain-id', type=_domain, default=None, metavar='N', help=(
        'ROS_DOMAIN_ID to start the graph in (default: a free one)' if graph == 'start' else
        'ROS_DOMAIN_ID of the running graph (default: the environment\'s, else 0)'))
    if graph == 'wait':
        parser.add_argument('--wait', type=_positive, default=30.0, metavar='S',
                            help='[s] to wait for the graph\'s servers to answer')
        _namespace_option(parser)


def _namespace_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--namespace', type=_namespace, default='', metavar='NS',
                        help='the arm\'s namespace (flexarm up --namespace NS; default none)')


def _namespace(value: str) -> str:
    name = value.strip('/')
    if name and not all(part.isidentifier() for part in name.split('/')):
        raise argparse.ArgumentTypeError(f'{value!r} is not a ROS namespace (letters, digits, '
                                         '_ and / between names)')
    return name


def _calibrate_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--reference-topic', default=topics.TIP_POSE_TRUTH, metavar='TOPIC',
                   help='flexarm_msgs/TipPose of the reference instrument (a laser tracker at '
                        "the tool point); in simulation the simulator's ground truth")
    p.add_argument('--timeout', type=_positive, default=120.0, metavar='S',
                   help='[s] per pose, for the move and for the reference')
    p.add_argument('--file', default='', metavar='PATH',
                   help="where to store it (default: calibration/tool_camera.json, the vision "
                        "node's tool_calibration_file)")
    p.add_argument('--camera', action='store_true',
                   help="first calibrate the camera's own parameters from the plate (focal "
                        'length over stand-off, radial distortion k1, k2) at the same poses: '
                        'for a camera refocused, remounted or off its camera_info')
    p.add_argument('--camera-file', default='', metavar='PATH',
                   help="where to store the camera's (default: calibration/camera.json, the "
                        "vision node's camera_calibration_file)")


def _move_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('x', type=_finite, help='target x [mm] (horizontal, base frame)')
    p.add_argument('y', type=_finite, help='target y [mm] (up)')
    p.add_argument('phi', type=_finite, help='target tool angle [deg] from +x')
    p.add_argument('--mode', choices=MODE_LABELS,
                   default='predictive',
                   help='rigid: rigid inverse kinematics; predictive: compensate the learned '
                        'deflection (needs a model); closed_loop: predictive (rigid without a '
                        'model), then corrected from the measured tip')
    p.add_argument('--position-tolerance', type=_non_negative, default=0.0, metavar='MM',
                   help='[mm] CLOSED_LOOP corrects until within it (0: the compensator\'s '
                        'default); RIGID/PREDICTIVE: if given, the measured error must be '
                        'within it, else TOLERANCE_NOT_MET')
    p.add_argument('--angle-tolerance', type=_non_negative, default=0.0, metavar='DEG',
                   help='[deg] as --position-tolerance, for the tool angle')
    p.add_argument('--max-corrections', type=_natural, default=0, metavar='N',
                   help='CLOSED_LOOP only: corrective moves after the first (0: the '
                        'compensator\'s default)')
    p.add_argument('--allow-extrapolation', action='store_true',
                   help='run a PREDICTIVE goal beyond the learned data (with a warning) '
                        'instead of refusing it')
    p.add_argument('--trial', default='', help='trial name for logs and bags')
    p.add_argument('--dry-run', action='store_true',
                   help='only plan: print the commanded pose, joints, predicted deflection, '
                        'distance to the learned data and model; nothing moves')
    p.add_argument('--timeout', type=_positive, default=300.0, metavar='S',
                   help='[s] for the goal; then it is cancelled')


def _collect_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('count', type=_positive_int, metavar='N', help='samples to collect')
    p.add_argument('--region', default='',
                   help='region preset of config/learner.yaml (default: the learner\'s, '
                        f'{_learner_default("default_region")})')
    p.add_argument('--strategy', default='',
                   help='sobol | halton | lhs | random | active (each pose where the model '
                        'so far is least sure; default: the learner\'s, '
                        f'{_learner_default("default_strategy")})')
    p.add_argument('--seed', type=_natural, default=0, help='seed of the sampling strategy')
    p.add_argument('--dataset', default='',
                   help='dataset name: data/NAME.jsonl (default: the learner\'s, '
                        f'{_learner_default("default_dataset")})')
    p.add_argument('--payload', type=_non_negative, metavar='KG',
                   help='[kg] declare the payload the arm carries first (stored with every '
                        'sample; default: as declared before)')
    p.add_argument('--timeout', type=_positive, default=3600.0, metavar='S',
                   help='[s] for the collection; then it is cancelled')


def _refresh_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--count', type=_natural, default=0, metavar='N',
                   help='samples to take (default: the learner\'s refresh_samples, 8)')
    p.add_argument('--region', default='',
                   help='region preset to refresh (default: the ones the model health '
                        'reports stale)')
    p.add_argument('--force', action='store_true',
                   help='refresh --region even where the model health sees the model fit '
                        '(it would fit measurement noise)')
    p.add_argument('--timeout', type=_positive, default=1800.0, metavar='S',
                   help='[s] for the refresh; then it is cancelled')


def _payload_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('kg', nargs='?', type=_non_negative, metavar='KG',
                   help='[kg] the payload the arm carries from now on (default: only show it)')


KIND_HELP = ('predictor kind: auto (the best of kinematic, greybox and gp by cross-validation) '
             '| kinematic | greybox | gp | mlp | rbf')


def _kind_help() -> str:
    """KIND_HELP and the learner's default kind, read so that the help cannot drift."""
    return f"{KIND_HELP} (default: the learner's, {_learner_default('default_kind')})"


def _train_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('kind', nargs='?', default='', help=_kind_help())
    p.add_argument('--settings', type=_json_object, default={},
                   help='kind-specific settings, a JSON object, e.g. \'{"hidden": [10]}\' '
                        '(default: the kind\'s)')
    p.add_argument('--dataset', default='', help='dataset name (default: the learner\'s)')
    p.add_argument('--timeout', type=_positive, default=300.0, metavar='S',
                   help='[s] for the training')


IDEAL_HELP = ('the ideal simulated world: every error source of config/sim.yaml off (exact '
              'joints, no hysteresis or thermal drift, a perfectly calibrated camera), as in '
              'the paper comparison; default: the realistic world')


def _world(args: argparse.Namespace) -> dict[str, Any]:
    """Simulator parameters of the world ``--ideal`` chooses (none: config/sim.yaml's)."""
    return {'error_sources': {'enabled': False}} if args.ideal else {}


def _up_arguments(p: argparse.ArgumentParser) -> None:
    _namespace_option(p)
    p.add_argument('--ideal', action='store_true', help=IDEAL_HELP)
    p.add_argument('--robot', default='sim', help='controller entry of config/graph.yaml')
    p.add_argument('--record', default='', metavar='NAME', help='record bags/NAME/NAME.mcap')
    p.add_argument('--record-images', action='store_true',
                   help='with --record: also record /camera/image_raw (~9 MB/s)')
    p.add_argument('--foxglove', nargs='?', type=_port, const=0, default=None, metavar='PORT',
                   help='serve the live graph to Foxglove at ws://HOST:PORT (config/'
                        'foxglove.yaml: HOST 127.0.0.1, default PORT 8765)')
    p.add_argument('--rtf', type=_positive, default=1.0, help='simulator real-time factor')
    p.add_argument('--name', default='', help='run folder runs/NAME (default: up-DATE-TIME)')
    p.add_argument('--timeout', type=_positive, default=60.0, metavar='S',
                   help='[s] to become ready')
    p.add_argument('--link-key', default='', metavar='FILE',
                   help='site key of the controller link (made by flexarm keygen FILE); '
                        'required when the controller is not on this machine')
    p.add_argument('--discovery', choices=['localhost', 'subnet'], default='localhost',
                   help='DDS range (default: this machine only); subnet: anyone on the '
                        'network can command the arm (no DDS-Security in these wheels)')
    p.add_argument('--only', type=lambda text: tuple(text.split(',')), default=(),
                   metavar='NODES', help='start only these nodes of config/graph.yaml, comma-'
                   'separated, flexarm_ prefix optional (e.g. sim,vision); the rest of the '
                   'graph runs on other hosts of the domain (default: the whole graph)')
    p.add_argument('--outlive-parent', action='store_true',
                   help='keep the graph running after the process that started `up` has '
                        'ended, e.g. `nohup flexarm up --outlive-parent &` (default: it stops '
                        'with that process as on Ctrl-C, so a script, test or shell that dies '
                        'leaves no graph behind; a terminal closing stops it unless nohup)')


def _experiment_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--samples', type=_positive_int, default=40,
                   help='learning samples per region')
    p.add_argument('--kind', default='', help=_kind_help())
    p.add_argument('--rtf', type=_positive, default=10.0, help='simulator real-time factor')
    p.add_argument('--seed', type=_natural, default=1, help='seed of samples and targets')
    p.add_argument('--name', default='',
                   help='results/NAME, bags/NAME, runs/NAME (default: COMMAND-DATE-TIME)')
    p.add_argument('--no-record', action='store_true', help='do not write a bag')
    p.add_argument('--ideal', action='store_true', help=IDEAL_HELP)


def _benchmark_arguments(p: argparse.ArgumentParser) -> None:
    _experiment_arguments(p)
    p.add_argument('--random', type=_natural, default=50,
                   help='held-out random targets per region A and B')


def _study_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--region', default='paper', help='region preset of config/learner.yaml')
    p.add_argument('--seeds', type=_positive_int, default=3,
                   help='repetitions of every configuration')
    p.add_argument('--quick', action='store_true', help='small grid, for a smoke run')
    p.add_argument('--out', default=str(RESULTS_DIR / 'study'),
                   help='results go to OUT/REGION/')


def _bag_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('action', choices=['info', 'export'])
    p.add_argument('path', help='bag folder (bags/NAME) or .mcap file')
    p.add_argument('--out', default='', help='export folder (default: the bag folder)')
    _namespace_option(p)


def _model_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('action', choices=['list', 'use'])
    p.add_argument('version', nargs='?', default='', help='use: the model version to make '
                   'current again (roll back); the compensator switches to it')
    p.add_argument('--models', default='', metavar='DIR',
                   help="list: the learner's model directory (default: models/, models/NS "
                        'with --namespace NS)')


def _keygen_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('path', help='key file to create')


def _down_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--domain-id', type=_domain, default=None, metavar='N',
                   help='ROS_DOMAIN_ID of the running graph to stop (default: the only graph '
                        'running on this machine; see flexarm ps)')
    p.add_argument('--namespace', type=_namespace, default=None, metavar='NS',
                   help="the arm's namespace (flexarm up --namespace NS; default: whichever "
                        'arm runs in the domain, if only one does)')
    p.add_argument('--timeout', type=_positive, default=30.0, metavar='S',
                   help='[s] to wait for the graph to end (its supervisor stops each node '
                        'with SIGINT, then SIGTERM, then SIGKILL)')


# subcommand: (its arguments, graph options (_graph_options): None = none, 'start' = it starts
# a graph, 'running' = it asks a running one, 'wait' = it sends requests to a running one)
SUBCOMMANDS: dict[str, tuple[Callable[[argparse.ArgumentParser], None], str | None]] = {
    'up': (_up_arguments, 'start'),
    'status': (_namespace_option, 'running'),
    'ps': (lambda p: None, None),
    'down': (_down_arguments, None),
    'move': (_move_arguments, 'wait'),
    'collect': (_collect_arguments, 'wait'),
    'train': (_train_arguments, 'wait'),
    'refresh': (_refresh_arguments, 'wait'),
    'payload': (_payload_arguments, 'wait'),
    'cancel': (lambda p: None, 'wait'),
    'demo': (_experiment_arguments, 'start'),
    'benchmark': (_benchmark_arguments, 'start'),
    'study': (_study_arguments, None),
    'bag': (_bag_arguments, None),
    'model': (_model_arguments, 'wait'),
    'keygen': (_keygen_arguments, None),
    'calibrate': (_calibrate_arguments, 'wait'),
}


def build_parser() -> argparse.ArgumentParser:
    epilog = 'exit codes:\n' + '\n'.join(
        textwrap.fill(text, 79, initial_indent=f'  {int(code):>3}  ', subsequent_indent=' ' * 7)
        for code, text in EXIT_MEANINGS.items())
    parser = argparse.ArgumentParser(prog='flexarm', description=__doc__.splitlines()[0]
                                     .replace('``', ''),
                                     epilog=epilog, formatter_class=_HelpFormatter)
    _output_options(parser, False)
    output = argparse.ArgumentParser(add_help=False)
    _output_options(output, argparse.SUPPRESS)     # after the subcommand: only when given
    sub = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')
    for name, (arguments, graph) in SUBCOMMANDS.items():
        doc = COMMANDS[name].__doc__
        p = sub.add_parser(name, help=doc, description=doc, parents=[output],
                           formatter_class=_HelpFormatter)
        arguments(p)
        if graph is not None:
            _graph_options(p, graph)
    return parser


def _run(args: argparse.Namespace) -> tuple[dict[str, Any], Exit]:
    """The command's result and exit code; any outcome but success said on stderr."""
    fields: dict[str, Any] = {}
    try:
        result = COMMANDS[args.command](args)
        return result, Exit.OK
    except Outcome as exc:
        message, code, fields = str(exc), exc.code, exc.fields
    except TimeoutError as exc:
        message, code = str(exc), Exit.NO_GRAPH
    except KeyboardInterrupt:
        message, code = 'interrupted', Exit.INTERRUPTED
    except (ValueError, RuntimeError, OSError) as exc:
        message, code = str(exc), Exit.FAILED
    print(f'flexarm {args.command}: {message}', file=sys.stderr, flush=True)
    return {'ok': False, 'error_string': message} | fields | {'outcome': message}, code


def main(argv: Sequence[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:        # --help (0), or a usage error argparse has printed (2)
        return int(exc.code or 0)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    transport.apply(os.environ)    # before any participant: Fast DDS reads its profile once
    # SIGTERM stops a command like Ctrl-C does: a running goal is cancelled and a graph it
    # started is shut down (its nodes run in sessions of their own and do not get the signal).
    # Both go through _interrupt, which keeps them out of rclpy's message conversions.
    previous = {s: signal.signal(s, _interrupt) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        result, code = _run(args)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if args.json:
        print(json.dumps(result | {'exit_code': int(code)}))
    return int(code)


def run() -> None:
    """The ``flexarm`` command: :func:`main`, then exit at once with its code.

    Output is flushed, then the interpreter's teardown is skipped: after a server died with
    SIGKILL, Fast DDS spends seconds at exit on the dead participant's shared memory, and the
    user would wait that long for the prompt after the outcome was already said.
    """
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == '__main__':
    run()
