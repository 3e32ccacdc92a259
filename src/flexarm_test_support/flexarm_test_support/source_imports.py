"""What source files import, read from their syntax trees without running them: the checks of
the packages' declared dependencies and the environment's pins ask it."""
from __future__ import annotations

import ast
import sys
from collections.abc import Iterable
from pathlib import Path


def third_party_imports(paths: Iterable[Path], root: Path,
                        local: Iterable[str] = ()) -> dict[str, set[str]]:
    """Top-level names the modules at ``paths`` (files, or folders read recursively) import
    that are neither the standard library, nor flexarm, nor one of ``local``: each with the
    files importing it, relative to ``root``."""
    local = set(local)
    names: dict[str, set[str]] = {}
    for folder in paths:
        for path in [folder] if folder.is_file() else sorted(folder.rglob('*.py')):
            for name in imported_names(path.read_text(encoding='utf-8')):
                if not (name in sys.stdlib_module_names or name.startswith('flexarm_')
                        or name in local):
                    names.setdefault(name, set()).add(path.relative_to(root).as_posix())
    return names


def imported_names(text: str) -> set[str]:
    """The top-level names a module's ``text`` imports absolutely, at its top or inside a
    function alike."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            names.update(alias.name.split('.')[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split('.')[0])
    return names
