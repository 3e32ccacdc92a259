"""Code a reader can hold: no function of a package longer than a screen and a half, no
package so large that its name stops saying what it holds (split it by product instead)."""
from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / 'src'
MAX_FUNCTION_LINES = 80
MAX_PACKAGE_LINES = 4000


def modules(package: Path) -> list[Path]:
    """The package's own modules (``src/<pkg>/<pkg>/``), not its tests."""
    return sorted((package / package.name).rglob('*.py'))


def long_functions(text: str, limit: int = MAX_FUNCTION_LINES) -> list[str]:
    """``line name (N lines)`` of every function or method of ``text`` longer than ``limit``."""
    return [f'{node.lineno} {node.name} ({node.end_lineno - node.lineno + 1} lines)'
            for node in ast.walk(ast.parse(text))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            and node.end_lineno - node.lineno + 1 > limit]


def test_no_function_is_longer_than_80_lines():
    found = [f'{path.relative_to(SRC)}:{f}' for package in SRC.iterdir()
             for path in modules(package)
             for f in long_functions(path.read_text(encoding='utf-8'))]
    assert not found, found


def test_a_long_method_is_found():
    body = ''.join(f'        x{i} = {i}\n' for i in range(MAX_FUNCTION_LINES))
    text = f'def short():\n    pass\n\n\nclass C:\n    def long(self):\n{body}'
    assert long_functions(text) == [f'6 long ({MAX_FUNCTION_LINES + 1} lines)']


def test_no_package_is_over_4000_lines():
    sizes = {package.name: sum(len(path.read_text(encoding='utf-8').splitlines())
                               for path in modules(package))
             for package in SRC.iterdir() if (package / 'package.xml').exists()}
    over = {name: lines for name, lines in sizes.items() if lines > MAX_PACKAGE_LINES}
    assert not over, over
