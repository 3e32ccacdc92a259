"""The test suite as every contributor and CI meets it: the README's test command, N times, in a
fresh clone of HEAD; per run the wall time, the tests passed and failed and the failing ids.
``failures`` counts the failing tests over all runs.

The clone is set up once (``scripts/setup.sh``: a new venv, minutes; not counted), with the
checkout's neighbouring ``shared`` folder beside it (the real measurements some benchmarks
read), then each run executes the README's test command there (its set-up step then takes
about a second).
``median_s`` and ``max_s`` are pytest's own times (set-up excluded), ``wall_s`` per run is the
whole command. ``--hog`` keeps every core busy with a spinning process for the whole run: a
loaded CI runner, where a suite that waits on guessed wall-clock times fails. The test command
(bash execs its last command: pytest), the set-up and the busy loops end when this process
ends, however (the tests' graphs end with pytest).

    python benchmarks/suite.py [--runs 5] [--hog] [--json]
    python benchmarks/suite.py --here --runs 1 --tests src/flexarm_control/test/test_modes.py
        (smoke: this checkout, no clone, a few tests)
"""
from __future__ import annotations

import argparse
import ctypes
import json
import multiprocessing
import os
import re
import shlex
import signal
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SUMMARY = re.compile(r'=+ (?P<counts>.*?) in (?P<seconds>[\d.]+)s')
FAILED = re.compile(r'^(FAILED|ERROR) (\S+)', re.M)
PRCTL = ctypes.CDLL(None, use_errno=True).prctl   # looked up before any fork


def test_command(readme: Path) -> str:
    """The README's test command: the command line of its opening block that runs pytest."""
    for line in readme.read_text(encoding='utf-8').splitlines():
        if 'pytest' in line and not line.lstrip().startswith('#'):
            return line.split('#', 1)[0].strip()
    raise ValueError(f'{readme} names no test command')


def clean_env() -> dict[str, str]:
    """The environment CI gives the command (.ci/run): no venv or ROS bootstrap of ours, and
    none of a venv's libraries on LD_LIBRARY_PATH (what the bootstrap of this checkout's venv
    put there). Kept, the clone's processes loaded this checkout's message libraries or the
    clone's own, each process at random (ros_wheels_bootstrapper orders LD_LIBRARY_PATH as a
    set: by the process's string hashes): with a message changed in this working tree, the
    scene node silently dropped every DeflectionSample of an older layout and
    test_visibility waited 120 s for the sample on /scene/markers."""
    env = dict(os.environ)
    for name in ('VIRTUAL_ENV', '_ROS_WHEELS_BOOTSTRAP_COMPLETE', 'PYTHONPATH', 'PYTHONHOME',
                 'ROS_DOMAIN_ID', 'FLEXARM_STATE_DIR', 'FLEXARM_LIVENESS_SCALE'):
        env.pop(name, None)
    kept = [part for part in env.pop('LD_LIBRARY_PATH', '').split(os.pathsep)
            if part and not in_venv(Path(part))]
    if kept:
        env['LD_LIBRARY_PATH'] = os.pathsep.join(kept)
    return env


def in_venv(path: Path) -> bool:
    """Whether ``path`` lies in a Python virtual environment (a directory with pyvenv.cfg)."""
    return any((folder / 'pyvenv.cfg').is_file() for folder in (path, *path.parents))


def _die_with_parent(sig: int) -> None:
    """``sig`` to this process when the thread that started it ends (PR_SET_PDEATHSIG; as
    flexarm_core.parent_death, which this script, run outside the venv, cannot import)."""
    PRCTL(1, int(sig), 0, 0, 0)


def terminate_with_parent() -> None:
    """A ``preexec_fn``: SIGTERM to the child when this harness ends, also by SIGKILL."""
    _die_with_parent(signal.SIGTERM)


def spin() -> None:
    """A busy core until this harness ends (also by SIGKILL)."""
    _die_with_parent(signal.SIGKILL)
    while True:
        pass


def run_once(tree: Path, command: str, log: Path) -> dict:
    """One run of ``command`` in ``tree``: wall time, pytest's time and counts, failing ids."""
    start = time.monotonic()
    with open(log, 'w', encoding='utf-8') as out:
        code = subprocess.run(['bash', '-c', command], cwd=tree, env=clean_env(), stdout=out,
                              stderr=subprocess.STDOUT, check=False,
                              preexec_fn=terminate_with_parent).returncode
    wall = time.monotonic() - start
    text = log.read_text(encoding='utf-8', errors='replace')
    summaries = list(SUMMARY.finditer(text))
    counts = {'passed': 0, 'failed': 0, 'errors': 0}
    seconds = None
    if summaries:
        last = summaries[-1]
        seconds = float(last['seconds'])
        for number, word in re.findall(r'(\d+) (\w+)', last['counts']):
            key = {'error': 'errors', 'errors': 'errors'}.get(word, word)
            if key in counts:
                counts[key] = int(number)
    failing = sorted({m.group(2) for m in FAILED.finditer(text)})
    if code != 0 and not failing:
        failing = [f'(exit code {code}, no failing test named: see {log})']
    return {'exit_code': code, 'wall_s': round(wall, 1),
            'pytest_s': seconds, **counts, 'failing': failing, 'log': str(log)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', type=int, default=5)
    parser.add_argument('--hog', action='store_true',
                        help='a busy loop on each core for the whole run')
    parser.add_argument('--here', action='store_true',
                        help='run in this checkout instead of a fresh clone of HEAD')
    parser.add_argument('--tests', default='',
                        help='pytest arguments appended to the command (default: none, the '
                             'whole suite)')
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    if args.runs < 1:
        parser.error('--runs must be at least 1')

    with tempfile.TemporaryDirectory(prefix='flexarm-suite-') as tmp:
        tree = ROOT
        if not args.here:
            tree = Path(tmp) / 'flexarm'
            subprocess.run(['git', 'clone', '--quiet', str(ROOT), str(tree)], check=True)
            shared = ROOT.parent / 'shared'
            if shared.is_dir():          # beside the clone, as beside every checkout
                (Path(tmp) / 'shared').symlink_to(shared)
            print(f'fresh clone of {ROOT} HEAD in {tree}; setting up (not timed)', flush=True)
            with open(Path(tmp) / 'setup.log', 'w', encoding='utf-8') as out:
                subprocess.run(['scripts/setup.sh'], cwd=tree, env=clean_env(), stdout=out,
                               stderr=subprocess.STDOUT, check=True,
                               preexec_fn=terminate_with_parent)
        command = test_command(tree / 'README.md')
        if args.tests:
            command += ' ' + ' '.join(shlex.quote(a) for a in shlex.split(args.tests))
        logs = Path(tempfile.mkdtemp(prefix='flexarm-suite-logs-'))
        runs = []
        for index in range(args.runs):
            hogs = [multiprocessing.Process(target=spin, daemon=True)
                    for _ in range(os.cpu_count() or 1)] if args.hog else []
            for hog in hogs:
                hog.start()
            try:
                run = run_once(tree, command, logs / f'run{index + 1}.log')
            finally:
                for hog in hogs:
                    hog.kill()
                    hog.join()
            runs.append(run)
            print(f'run {index + 1}/{args.runs}: {run["wall_s"]:.0f} s wall, pytest '
                  f'{run["pytest_s"]} s, {run["passed"]} passed, {run["failed"]} failed, '
                  f'{run["errors"]} errors{" (hog)" if args.hog else ""}'
                  + ''.join(f'\n    {test}' for test in run['failing']), flush=True)

    times = [r['pytest_s'] for r in runs if r['pytest_s'] is not None]
    failures = sum(len(r['failing']) for r in runs)   # failing tests, over all runs
    summary = {'command': command, 'tree': 'this checkout' if args.here else 'fresh clone',
               'runs': runs, 'failures': failures,
               'median_s': statistics.median(times) if times else None,
               'max_s': max(times) if times else None, 'logs': str(logs)}
    if args.hog:
        summary['hog'] = {'cores': os.cpu_count(), 'failures': failures}
    print(f'{args.runs} run(s): {failures} failing test(s) in all, pytest median '
          f'{summary["median_s"]} s, max {summary["max_s"]} s; logs in {logs}')
    if args.json:
        print(json.dumps(summary))


if __name__ == '__main__':
    main()
