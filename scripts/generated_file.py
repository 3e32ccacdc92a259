"""What the generators of scripts/ share: write the file they make (atomically), or check that
it is what they would make (``--check``, for a test)."""
from __future__ import annotations

import sys
from pathlib import Path

from flexarm_core.atomic_file import atomic_write

ROOT = Path(__file__).resolve().parents[1]


def write_or_check(path: Path, text: str, check: bool) -> int:
    """Exit code: 0, or 1 when checking a file that differs from ``text``."""
    if check:
        if not path.is_file() or path.read_text(encoding='utf-8') != text:
            print(f'{path.relative_to(ROOT)} is out of date: run python '
                  f'{Path(sys.argv[0]).resolve().relative_to(ROOT)}', file=sys.stderr)
            return 1
        return 0
    path.parent.mkdir(exist_ok=True)
    atomic_write(path, lambda f: f.write(text.encode('utf-8')))
    return 0
