"""Where flexarm_core.paths finds config/ when it does not run from the clone: FLEXARM_HOME first,
else flexarm_core's share directory through the ament index, else a clear error. The module is
loaded from a copy placed as an install puts it (``<prefix>/lib/python3.X/site-packages``)."""
from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path
from types import ModuleType

import pytest

from flexarm_core import paths


def load_installed(prefix: Path) -> ModuleType:
    """A fresh copy of flexarm_core.paths as installed under ``prefix`` (outside any clone)."""
    target = prefix / 'lib/python3.11/site-packages/flexarm_core/paths.py'
    target.parent.mkdir(parents=True)
    shutil.copy(paths.__file__, target)
    spec = importlib.util.spec_from_file_location('installed_paths', target)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def outside(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A working directory of no clone, with none of the variables that name one."""
    for name in ('FLEXARM_HOME', 'FLEXARM_STATE_DIR', 'AMENT_PREFIX_PATH'):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_an_install_takes_config_from_its_share_directory(outside, monkeypatch):
    prefix = outside / 'install'
    (prefix / 'share/flexarm_core/config').mkdir(parents=True)
    (prefix / 'share/ament_index/resource_index/packages').mkdir(parents=True)
    (prefix / 'share/ament_index/resource_index/packages/flexarm_core').touch()
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(prefix))
    installed = load_installed(prefix)
    assert installed.CONFIG_DIR == prefix / 'share/flexarm_core/config'
    assert installed.DATA_DIR == outside / 'data'


def test_flexarm_home_wins_over_the_install(outside, monkeypatch):
    monkeypatch.setenv('FLEXARM_HOME', str(outside / 'clone'))
    installed = load_installed(outside / 'install')
    assert installed.CONFIG_DIR == outside / 'clone/config'
    assert installed.MODELS_DIR == outside / 'clone/models'


def test_an_install_in_no_ament_index_says_what_to_do(outside):
    with pytest.raises(RuntimeError, match='FLEXARM_HOME'):
        load_installed(outside / 'install')
