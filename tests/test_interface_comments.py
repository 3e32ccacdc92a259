"""The interfaces' comments name modules that exist: docs/interfaces.md is generated from them,
and a module path that moved leaves a reader nowhere to look."""
import importlib.util
import re

import pytest

from flexarm_core.paths import SOURCE

DEFINITIONS = sorted(p for p in (SOURCE / 'src' / 'flexarm_msgs').rglob('*')
                     if p.suffix in ('.msg', '.srv', '.action'))
NAMED = re.compile(r'\b(flexarm_[a-z_]+(?:\.[a-z_]+)+)')


def _module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


@pytest.mark.parametrize('path', DEFINITIONS, ids=lambda p: p.name)
def test_every_module_an_interface_names_exists(path):
    for name in NAMED.findall(path.read_text()):
        assert _module(name) or _module(name.rpartition('.')[0]), (
            f'{path.name} names {name}: no such module (nor a name in one)')
