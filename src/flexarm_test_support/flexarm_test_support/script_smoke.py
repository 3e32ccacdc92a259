"""A script's smoke run: a benchmark or an endurance harness at its smallest size, run as a
reader runs it (``python <folder>/<name>.py ... --json``) and checked: it exits 0, and its JSON
line (the last of stdout) holds the keys a reader relies on, numbers finite where they must
be. The figures themselves stay the scripts' job: nothing here judges a value."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import pytest

from flexarm_core.parent_death import terminate_with_parent
from flexarm_core.paths import SOURCE

TAIL = 3000    # [characters] of a failed run's output shown


@dataclass(frozen=True)
class Smoke:
    """One script's smoke run: a benchmark's, or an endurance harness's (tests/endurance/)."""

    name: str                    # the script <folder>/<name>.py (:func:`run`, from the clone)
    args: tuple[str, ...]        # its smallest size
    keys: tuple[str, ...]        # top-level keys of its JSON
    finite: tuple[str, ...] = ()  # dotted paths (list index or key) to finite numbers
    timeout: float = 90.0        # [s] wall, then the child is killed
    domain: str = ''             # its option that takes the test's ROS domain, if any
    check: Callable[[dict[str, Any]], None] | None = None   # more to check in its JSON
    seconds: float = 5.0         # [s] about how long it runs in the suite (scheduling only)

    def __str__(self) -> str:
        return self.name



def scheduled(smoke: Smoke) -> Any:
    """The smoke run as a test parameter with its expected duration (conftest's scheduler
    runs each of this module's tests as a unit of its own, the longest first)."""
    return pytest.param(smoke, marks=pytest.mark.duration(smoke.seconds))


def run(smoke: Smoke, domain_id: int | None = None, folder: str = 'benchmarks'
        ) -> dict[str, Any]:
    """Run the script ``folder/<name>.py`` (killed after its timeout); its JSON line,
    checked."""
    command = [sys.executable, f'{folder}/{smoke.name}.py', *smoke.args, '--json']
    if smoke.domain:
        command += [smoke.domain, str(domain_id)]
    try:
        done = subprocess.run(command, cwd=SOURCE, capture_output=True, text=True,
                              timeout=smoke.timeout, stdin=subprocess.DEVNULL,
                              preexec_fn=terminate_with_parent)   # ends with this test
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f'{smoke.name} still ran after {smoke.timeout:.0f} s (killed):\n'
                    f'{_tail(exc.stdout)}\n{_tail(exc.stderr)}')
    assert done.returncode == 0, (f'{smoke.name} exited with code {done.returncode}:\n'
                                  f'{_tail(done.stdout)}\n{_tail(done.stderr)}')
    lines = done.stdout.strip().splitlines()
    assert lines, f'{smoke.name} printed nothing:\n{_tail(done.stderr)}'
    try:
        figures = json.loads(lines[-1])
    except json.JSONDecodeError as exc:
        pytest.fail(f'{smoke.name}: the last line is not JSON ({exc}): {lines[-1][:500]}')
    missing = [key for key in smoke.keys if key not in figures]
    assert not missing, f'{smoke.name}: no {missing} in its JSON (keys: {sorted(figures)})'
    for path in smoke.finite:
        value = _at(figures, path)
        assert isinstance(value, int | float) and math.isfinite(value), (
            f'{smoke.name}: {path} is {value!r}, not a finite number')
    if smoke.check is not None:
        smoke.check(figures)
    return figures


def _at(tree: Any, path: str) -> Any:
    """The value at a dotted ``path`` (list index or key per part); fails the test if absent."""
    for part in path.split('.'):
        try:
            tree = tree[int(part)] if isinstance(tree, list) else tree[part]
        except (KeyError, IndexError, TypeError, ValueError):
            pytest.fail(f'no {path!r} in the JSON (at {part!r})')
    return tree


def _tail(text: str | bytes | None) -> str:
    if isinstance(text, bytes):
        text = text.decode(errors='replace')
    return (text or '')[-TAIL:]
