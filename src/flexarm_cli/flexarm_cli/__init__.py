"""``flexarm``: the command line of the flexarm system.

Humans type millimetres and degrees and read them back (every printed pose carries its units);
everything below the CLI is SI, and so is the ``--json`` result. Every outcome is said in words:
results on stdout, anything else (refused, failed, busy, timeout, interrupted) on stderr as
``flexarm COMMAND: …``; ``--json`` ends stdout with one line of JSON holding the result and its
``exit_code`` (a usage error too). Arguments are checked before anything connects; ``--version``
says which flexarm this is. Whatever takes more than a moment shows progress on stderr (bars,
waiting lines, goal feedback) unless ``--quiet`` or ``--json``. The graph must be running
(``flexarm up``) for move/collect/train, in the same ROS_DOMAIN_ID. DDS stays on this machine
(ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, and transports confined to shared memory and loopback:
:mod:`flexarm_core.transport`) unless the environment sets another range or static
peers, or ``flexarm up --discovery subnet`` widens it on purpose.

Exit codes (:class:`flexarm_recording.results.outcome_text.Exit`):

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
import json
import os
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from flexarm_cli.arguments import SUBCOMMANDS, UsageError, build_parser
from flexarm_cli.common import Outcome
from flexarm_cli.graph import interrupt_handler
from flexarm_core import transport
from flexarm_core.graph_locks import SeveralGraphs, this_machines_graph
from flexarm_core.paths import SITE_ENV
from flexarm_recording.results.outcome_text import Exit

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = ('flexarm_cli',)


def _run(args: argparse.Namespace) -> tuple[dict[str, Any], Exit]:
    """The command's result and exit code; any outcome but success said on stderr."""
    fields: dict[str, Any] = {}
    try:
        result = SUBCOMMANDS[args.command][0](args)
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


def _in_site(site: str, argv: list[str], from_shell: bool) -> str:
    """Run this command in the site folder ``site``: every path of the process (and of the
    nodes it starts) is fixed when flexarm_core.paths is first imported, so a site other than
    ``FLEXARM_SITE``'s runs the command again in a process that has it from the start (from a
    shell: exec, the same pid). What is wrong, or '' when this process is in the site."""
    folder = Path(site).expanduser().resolve()
    if not folder.is_dir():
        return f'--site {site}: no such folder (make one: `flexarm site init {site}`)'
    if os.environ.get(SITE_ENV) and Path(os.environ[SITE_ENV]).expanduser().resolve() == folder:
        return ''
    if not from_shell:
        return f'--site {site} in a running process: set {SITE_ENV} before it starts'
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, [sys.executable, '-m', 'flexarm_cli', *argv],
              {**os.environ, SITE_ENV: str(folder)})
    return ''


def _graph_site(args: argparse.Namespace, from_shell: bool) -> str:
    """The site folder of the graph a client command in a shell of its own means (the one
    graph running on this machine, as it finds its domain), when nothing names one: so that
    ``flexarm calibrate`` in a second shell stores the site's calibration, not the clone's.
    '' when a site or a domain is given, or for commands that start a graph."""
    if (not from_shell or os.environ.get(SITE_ENV) or getattr(args, 'domain_id', None) is not None
            or SUBCOMMANDS[args.command][2] not in ('running', 'wait')):
        return ''
    try:
        graph = this_machines_graph(getattr(args, 'namespace', ''), os.environ)
    except SeveralGraphs:
        return ''                   # the client asks which, with --domain-id
    return graph.site if graph is not None else ''


def main(argv: Sequence[str] | None = None) -> int:
    from_shell = argv is None
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:        # --help or --version (0)
        return int(exc.code or 0)
    except UsageError as exc:
        print(exc, file=sys.stderr, flush=True)
        if '--json' in argv:
            message = str(exc).splitlines()[-1]
            print(json.dumps({'ok': False, 'error_string': message, 'outcome': message,
                              'exit_code': int(Exit.USAGE)}))
        return int(Exit.USAGE)
    site = args.site if args.site is not None else _graph_site(args, from_shell)
    if site and (message := _in_site(site, argv, from_shell)):
        print(f'flexarm: {message}', file=sys.stderr, flush=True)
        return int(Exit.USAGE)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    transport.apply(os.environ)    # before any participant: Fast DDS reads its profile once
    # SIGTERM stops a command like Ctrl-C does: a running goal is cancelled and a graph it
    # started is shut down (its nodes run in sessions of their own and do not get the signal).
    # Both go through interrupt_handler, which keeps them out of rclpy's message conversions.
    previous = {s: signal.signal(s, interrupt_handler) for s in (signal.SIGINT, signal.SIGTERM)}
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
