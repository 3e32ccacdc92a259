"""What every command shares: its outcome, units, progress on stderr, the checks made before
connecting, the session with a running graph and the goal wrapper."""
from __future__ import annotations

import argparse
import contextlib
import math
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any

from flexarm_core import topics
from flexarm_recording.results.outcome_text import (
    Exit,
    busy_text,
)


class Outcome(Exception):
    """A command's outcome other than success: its words, exit code and JSON fields."""

    def __init__(self, text: str, code: Exit, /, **fields: Any) -> None:
        super().__init__(text)
        self.code, self.fields = code, fields


def usage(message: str) -> Outcome:
    """A usage error: bad arguments, found before connecting."""
    return Outcome(message, Exit.USAGE)


def mm(value_m: float) -> float:
    return value_m * 1e3


def deg(value_rad: float) -> float:
    return math.degrees(value_rad)


def pose_dict(pose: Any) -> dict[str, float]:
    """A PlanarPose as a JSON-able dict in SI units."""
    return {'x': pose.x, 'y': pose.y, 'phi': pose.phi}


def show_progress(args: argparse.Namespace) -> bool:
    return not (args.quiet or args.json)


def progress_printer(args: argparse.Namespace) -> Callable[[str], None]:
    """``say(text)``: a progress line on stderr, unless --quiet or --json."""
    def say(text: str) -> None:
        if show_progress(args):
            print(text, file=sys.stderr, flush=True)
    return say


@contextlib.contextmanager
def timed_step(what: str, args: argparse.Namespace) -> Iterator[None]:
    """While the block runs: after a second, 'WHAT ... mm:ss' on stderr, counting."""
    if not show_progress(args):
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
def step_printer(what: str, args: argparse.Namespace) -> Iterator[Callable[[int, int, str], None]]:
    """A progress bar on stderr fed by ``progress(done, total, step)`` calls."""
    from tqdm import tqdm

    bars: list[Any] = []      # made by the first call, which knows the total

    def progress(done: int, total: int, step: str) -> None:
        if not bars:
            bars.append(tqdm(desc=what, total=total, unit='step', disable=not show_progress(args)))
        bars[0].set_postfix_str(step, refresh=False)
        bars[0].update(done - bars[0].n)

    try:
        yield progress
    finally:
        for bar in bars:
            bar.close()


def learner_settings() -> dict[str, Any]:
    from flexarm_bringup.launcher import node_name
    from flexarm_core.params import load_config

    return load_config('learner.yaml', node_name=node_name('learner'))


def learner_default(key: str) -> str:
    """The learner's default ``key`` for a help text, read so that the help cannot drift; its
    parameter's name where config/ is not beside the code (an install space without it)."""
    try:
        return str(learner_settings()[key])
    except (OSError, KeyError):
        return f'its {key} parameter'


def node_default(role: str, key: str) -> str:
    """The configured ``key`` of graph.yaml's node of ``role`` (from its params files, as it
    starts with them) for a help text, read so that the help cannot drift; its parameter's
    name where config/ cannot be read."""
    from flexarm_bringup.launcher import all_nodes, node_parameters

    try:
        spec = next(spec for spec in all_nodes() if spec.role == role)
        return str(node_parameters(spec)[key])
    except (OSError, KeyError, StopIteration, ValueError):
        return f'its {key} parameter'


def check_region(region: str) -> None:
    presets = learner_settings()['regions']
    if region and region not in presets:
        raise usage(f'unknown region "{region}"; presets of config/learner.yaml: '
                    f'{", ".join(presets)}')


def check_dataset(name: str) -> None:
    if name:
        from flexarm_deflection.dataset import dataset_name_error

        reason = dataset_name_error(name)
        if reason is not None:
            raise usage(reason)


def check_kind(kind: str) -> None:
    if kind:
        from flexarm_deflection.models import KINDS

        if kind not in KINDS:
            raise usage(f'unknown predictor kind "{kind}"; known kinds: {", ".join(KINDS)}')


def check_strategy(strategy: str) -> None:
    if strategy:
        from flexarm_deflection.sampling import STRATEGIES

        if strategy not in STRATEGIES:
            raise usage(f'unknown strategy "{strategy}"; known: {", ".join(STRATEGIES)}')


def check_bag_path(path: str) -> None:
    from flexarm_recording.bag_tools import MCAP_MAGIC, mcap_path

    try:
        file = mcap_path(path)
    except FileNotFoundError as exc:
        raise usage(f'{exc} (a bag is bags/NAME or its .mcap file)') from None
    with open(file, 'rb') as f:
        if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise usage(f'{file} is not an MCAP bag')


def graph_client(args: argparse.Namespace, learner_node: str = 'flexarm_learner') -> Any:
    """A client of the graph ``args`` address (``--domain-id``, ``--namespace``; without
    either domain, the one graph of this machine, said on stderr); several graphs without a
    ``--domain-id`` are a usage error naming their domains."""
    from flexarm_control.ros.client import init_client
    from flexarm_core.graph_locks import SeveralGraphs

    try:
        return init_client(args.domain_id, args.namespace, learner_node, progress_printer(args))
    except SeveralGraphs as exc:
        raise usage(str(exc)) from None


@contextlib.contextmanager
def client_session(args: argparse.Namespace, learner: bool) -> Iterator[Any]:
    """A client of the graph once its servers answer (a waiting line meanwhile); shut down
    when the block ends."""
    import rclpy

    from flexarm_bringup.launcher import node_name

    client = graph_client(args, node_name('learner'))
    try:
        domain = client.context.get_domain_id()
        try:
            with timed_step(f'waiting for the flexarm graph in ROS_DOMAIN_ID={domain}', args):
                client.wait_until_ready(timeout=args.wait, learner=learner)
        except KeyboardInterrupt:
            raise Outcome('interrupted while waiting for the graph; nothing was sent',
                          Exit.INTERRUPTED) from None
        yield client
    finally:
        client.destroy_node()
        rclpy.try_shutdown()


def namespaced_name(args: argparse.Namespace, name: str) -> str:
    """The full name of a graph name (:mod:`flexarm_core.topics`) of the arm addressed."""
    return topics.absolute(name, args.namespace)


def run_interruptible_goal(run: Callable[[], Any], server: str,
                           interrupted: Callable[[Any], str]) -> Any:
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


def no_result_text() -> str:
    from flexarm_control.ros.client import CANCEL_WAIT

    return f'cancelled; no result from the server within {CANCEL_WAIT:.0f} s'


IDEAL_HELP = ('the ideal simulated world: every error source of config/sim.yaml off (exact '
              'joints, no hysteresis or thermal drift, a perfectly calibrated camera), as in '
              'the paper comparison; default: the realistic world')


def world_settings(args: argparse.Namespace) -> dict[str, Any]:
    """Simulator parameters of the world ``--ideal`` chooses (none: config/sim.yaml's)."""
    return {'error_sources': {'enabled': False}} if args.ideal else {}
