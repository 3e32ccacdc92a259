"""The docs say the CLI as it is: docs/using.md's command reference is what
scripts/cli_doc.py generates from the parser, every option of every command and action is in
it, and every `flexarm` command line of a shell or text code block of README.md and docs/ parses
with the CLI's own parser. Pure: no ROS graph."""
from __future__ import annotations

import argparse
import os
import re
import shlex
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from flexarm_cli.arguments import UsageError, build_parser

REPO = Path(__file__).resolve().parents[1]
USING = REPO / 'docs/using.md'
PAGES = [REPO / 'README.md', *sorted((REPO / 'docs').glob('*.md'))]
SHELL_FENCES = {'', 'bash', 'sh', 'shell', 'console', 'text'}
# a `flexarm` command: at the line's start or after && ; |, a `$ ` prompt, VAR=value words,
# a path to the executable
INVOCATION = re.compile(r'(?:^|&&|;|\|)\s*(?:\$\s+)?(?:\w+=\S*\s+)*(?:\S*/)?flexarm\s')
OPERATORS = {'&&', '||', ';', '|', '&'}


def parsers(parser: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    """``parser`` and the parser of every command and action below it."""
    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from parsers(sub)


def code_lines(page: Path) -> Iterator[tuple[int, str]]:
    """(line number, line) of the shell and text code blocks of ``page``, a line continued
    with a trailing backslash joined to the next."""
    fence, pending, start = None, '', 0
    for number, line in enumerate(page.read_text(encoding='utf-8').splitlines(), 1):
        stripped = line.strip()
        if stripped.startswith('```'):
            fence = stripped[3:].strip() if fence is None else None
            continue
        if fence not in SHELL_FENCES:
            continue
        start = start if pending else number
        if stripped.endswith('\\'):
            pending += stripped[:-1] + ' '
            continue
        yield start, pending + stripped
        pending = ''


def commands(line: str) -> Iterator[list[str]]:
    """The arguments of each `flexarm` command of a shell ``line`` (its comment stripped)."""
    lexer = shlex.shlex(line, posix=True, punctuation_chars=True)
    lexer.whitespace_split = True
    segments: list[list[str]] = [[]]
    for word in lexer:
        if word in OPERATORS:
            segments.append([])
        else:
            segments[-1].append(word)
    for segment in segments:
        while segment and (segment[0] == '$' or re.fullmatch(r'\w+=\S*', segment[0])):
            segment.pop(0)
        if segment and Path(segment[0]).name == 'flexarm':
            yield segment[1:]


DOCS_COMMANDS = [(f'{page.relative_to(REPO)}:{number}', argv)
                 for page in PAGES for number, line in code_lines(page)
                 if INVOCATION.search(line) for argv in commands(line)]


def test_the_reference_is_what_the_parser_gives() -> None:
    """In a process of its own without a site, whose config/ would change the defaults."""
    env = {k: v for k, v in os.environ.items() if k not in ('FLEXARM_SITE', 'FLEXARM_STATE_DIR')}
    result = subprocess.run([sys.executable, str(REPO / 'scripts/cli_doc.py'), '--check'],
                            capture_output=True, text=True, timeout=60, env=env)
    assert result.returncode == 0, result.stderr


def test_every_command_action_and_option_is_in_using_md() -> None:
    text = USING.read_text(encoding='utf-8')
    missing = [f'{p.prog} {option}' for p in parsers(build_parser())
               for option in p._option_string_actions
               if not re.search(rf'(?<![\w-]){re.escape(option)}(?![\w-])', text)]
    missing += [p.prog for p in parsers(build_parser()) if f'# {p.prog}\n' not in text
                and p.prog != 'flexarm']
    assert not missing, f'docs/using.md lacks {missing}: run python scripts/cli_doc.py'


def test_the_docs_show_flexarm_commands() -> None:
    """The scan finds them: the README's, using.md's, a continued line's, one after &&."""
    where = {place.split(':')[0] for place, _ in DOCS_COMMANDS}
    assert {'README.md', 'docs/using.md', 'docs/accuracy.md'} <= where
    assert ['demo'] in [argv for _, argv in DOCS_COMMANDS]
    assert any('--plot' in argv for _, argv in DOCS_COMMANDS)


@pytest.mark.parametrize('place, argv', DOCS_COMMANDS,
                         ids=[f'{place} {" ".join(argv)}' for place, argv in DOCS_COMMANDS])
def test_every_command_of_the_docs_parses(place: str, argv: list[str]) -> None:
    try:
        build_parser().parse_args(argv)
    except UsageError as error:
        pytest.fail(f'{place}: flexarm {shlex.join(argv)}: {str(error).splitlines()[-1]}')
