"""The README's headline figures, re-measured: the demo as its first command runs it (with the
bag), the test suite as its second runs it, the graph's footprint and the demo's accuracy.

Runs each source benchmark as a reader would (commands below), keeps each figure with the
machine it ran on (cores, CPU model), the date and the command, writes them to
``benchmarks/headline.json`` (atomically) and the README's table between its
``<!-- headline:begin -->`` and ``<!-- headline:end -->`` marks, and says which figures no
longer hold: beyond the target the project states for them, or more than ``--slack`` worse
than the figure the README stated before.

    python benchmarks/headline.py [--only demo,footprint,suite] [--slack 0.2] [--json]
    python benchmarks/headline.py --only '' --no-write --json   (check the stored figures)

Sources (each also alone): ``flexarm demo --json`` (``seconds``, ``achieved_rtf``, the
Table 10 errors), ``benchmarks/footprint.py --json`` (cores idle and while collecting, the
recorder's among them), ``benchmarks/suite.py --runs 1 --json`` (pytest's time; a fresh clone:
minutes of set-up, not counted). A source left out keeps its figures of the last run.

JSON (last line): ``figures`` (name -> value, unit, target, machine, date, command),
``no_longer_hold`` (names, with why).
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
STORE = ROOT / 'benchmarks' / 'headline.json'
README = ROOT / 'README.md'
BEGIN, END = '<!-- headline:begin -->', '<!-- headline:end -->'
VENV = ROOT / '.venv' / 'bin'


@dataclass(frozen=True)
class Figure:
    """One headline figure: where it is read in its source's JSON, and what it must meet."""

    name: str
    source: str
    unit: str
    read: Callable[[dict[str, Any]], float]
    target: float
    lower_is_better: bool = True
    note: str = ''

    def meets(self, value: float) -> bool:
        return value <= self.target if self.lower_is_better else value >= self.target

    def worse_than(self, value: float, before: float, slack: float) -> bool:
        if self.lower_is_better:
            return value > before * (1 + slack)
        return value < before * (1 - slack)


def _mode_max(mode: str) -> Callable[[dict[str, Any]], float]:
    def read(demo: dict[str, Any]) -> float:
        return max(group[mode]['max_mm'] for group in demo['summary'].values()
                   if mode in group)
    return read


SOURCES: dict[str, list[str]] = {
    'demo': [str(VENV / 'flexarm'), 'demo', '--json'],
    'footprint': [str(VENV / 'python'), 'benchmarks/footprint.py', '--json'],
    'suite': [sys.executable, 'benchmarks/suite.py', '--runs', '1', '--json'],
}
FIGURES = [
    Figure('demo_seconds', 'demo', 's', lambda d: d['seconds'], 100.0,
           note='with its bag, as the README\'s first command runs it'),
    Figure('demo_achieved_rtf', 'demo', '×', lambda d: d['achieved_rtf'], 8.0,
           lower_is_better=False, note='sim time per wall second, asked ×10'),
    Figure('predictive_max_mm', 'demo', 'mm', _mode_max('predictive'), 0.09,
           note='Table 10 targets, true error'),
    Figure('closed_loop_max_mm', 'demo', 'mm', _mode_max('closed_loop'), 0.055,
           note='Table 10 targets, true error'),
    Figure('idle_x1_cores', 'footprint', 'cores', lambda f: f['idle_x1']['total_cores'], 0.15,
           note='the whole graph idle at ×1'),
    Figure('collect_x10_cores', 'footprint', 'cores',
           lambda f: f['collect_x10']['total_cores'], 2.0,
           note='the whole graph collecting at ×10'),
    Figure('recorder_collect_x10_cores', 'footprint', 'cores',
           lambda f: f['recorder']['cores']['collect_x10'], 0.15,
           note='the recorder while the graph collects at ×10'),
    Figure('suite_s', 'suite', 's', lambda s: s['median_s'], 300.0,
           note='pytest\'s own time, the README\'s test command in a fresh clone'),
    Figure('suite_failures', 'suite', 'tests', lambda s: s['failures'], 0.0),
]


def machine() -> str:
    """What the figures ran on: cores and CPU model."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                model = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    return f'{os.cpu_count()} cores, {model}'


def run_source(name: str) -> dict[str, Any]:
    """Run one source benchmark; its JSON (the last line of its output)."""
    command = SOURCES[name]
    print(f'running {" ".join(Path(c).name if c.startswith("/") else c for c in command)}',
          file=sys.stderr, flush=True)
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True,
                          stdin=subprocess.DEVNULL)
    lines = done.stdout.strip().splitlines()
    if not lines:
        raise RuntimeError(f'{name} printed nothing (exit {done.returncode}): '
                           f'{done.stderr[-2000:]}')
    return json.loads(lines[-1])


def measure(sources: list[str], stored: dict[str, Any]) -> dict[str, Any]:
    """The figures of ``sources`` measured now, the others as stored."""
    figures = dict(stored)
    when = datetime.datetime.now(datetime.UTC).strftime('%Y-%m-%d')
    where = machine()
    for source in sources:
        output = run_source(source)
        shown = ' '.join(['flexarm' if Path(SOURCES[source][0]).name == 'flexarm' else 'python',
                          *SOURCES[source][1:]])
        for figure in (f for f in FIGURES if f.source == source):
            try:
                value = float(figure.read(output))
            except (KeyError, TypeError, ValueError) as exc:
                figures[figure.name] = {'value': None, 'error': f'not in its JSON: {exc}',
                                        'date': when, 'machine': where, 'command': shown}
                continue
            figures[figure.name] = {'value': value, 'unit': figure.unit,
                                    'target': figure.target, 'date': when, 'machine': where,
                                    'command': shown, 'note': figure.note}
    return figures


def no_longer_hold(figures: dict[str, Any], before: dict[str, Any], slack: float
                   ) -> dict[str, str]:
    """Figures beyond their target, or worse than the README stated by more than ``slack``."""
    out = {}
    for figure in FIGURES:
        now = figures.get(figure.name, {})
        value = now.get('value')
        if value is None:
            out[figure.name] = now.get('error', 'not measured')
            continue
        was = before.get(figure.name, {}).get('value')
        if not figure.meets(value):
            out[figure.name] = (f'{value:.4g} {figure.unit} is beyond its target '
                                f'{figure.target:g} {figure.unit}')
        elif was is not None and figure.worse_than(value, was, slack):
            out[figure.name] = (f'{value:.4g} {figure.unit} against {was:.4g} stated '
                                f'({slack:.0%} slack)')
    return out


def table(figures: dict[str, Any]) -> str:
    rows = ['| figure | measured | target | machine, date | command |',
            '|---|---|---|---|---|']
    for figure in FIGURES:
        f = figures.get(figure.name)
        if not f or f.get('value') is None:
            continue
        bound = '≤' if figure.lower_is_better else '≥'
        label = figure.name + (f' ({figure.note})' if figure.note else '')
        rows.append(f'| {label} | {f["value"]:.4g} {figure.unit} | {bound} {figure.target:g} '
                    f'| {f["machine"]}, {f["date"]} | `{f["command"]}` |')
    return '\n'.join(rows)


def write_atomically(path: Path, text: str) -> None:
    with tempfile.NamedTemporaryFile('w', dir=path.parent, delete=False, encoding='utf-8',
                                     suffix='.tmp') as tmp:
        tmp.write(text)
    os.replace(tmp.name, path)


def update_readme(text: str) -> bool:
    """Replace the README's table between the marks; False if it has no marks."""
    readme = README.read_text(encoding='utf-8')
    if BEGIN not in readme or END not in readme:
        return False
    head, rest = readme.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    write_atomically(README, f'{head}{BEGIN}\n{text}\n{END}{tail}')
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--only', default=','.join(SOURCES),
                        help=f'sources to re-measure, comma-separated (of {", ".join(SOURCES)})')
    parser.add_argument('--slack', type=float, default=0.2,
                        help='a figure this much worse than stated no longer holds')
    parser.add_argument('--no-write', action='store_true',
                        help='write neither headline.json nor the README')
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    sources = [s.strip() for s in args.only.split(',') if s.strip()]
    unknown = set(sources) - set(SOURCES)
    if unknown:
        parser.error(f'unknown sources {sorted(unknown)}; choose of {sorted(SOURCES)}')
    before = json.loads(STORE.read_text(encoding='utf-8')) if STORE.exists() else {}
    figures = measure(sources, before)
    failing = no_longer_hold(figures, before, args.slack)
    if args.no_write:
        pass
    elif sources:
        write_atomically(STORE, json.dumps(figures, indent=1, ensure_ascii=False) + '\n')
    if not args.no_write and not update_readme(table(figures)):
        print(f'{README.name} has no {BEGIN} … {END} marks: table not written',
              file=sys.stderr)
    if not args.json:
        print(table(figures))
        for name, why in failing.items():
            print(f'no longer holds: {name}: {why}')
    print(json.dumps({'figures': figures, 'no_longer_hold': failing}, ensure_ascii=False))


if __name__ == '__main__':
    main()
