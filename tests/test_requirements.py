"""The pins of requirements/ in three sets: runtime (what a robot machine installs), docs (the
site) and test (the suite, over runtime and docs), one lock of exact versions. Each package is
pinned once, in the set that needs it; each set holds its whole closure, so it installs alone to
exactly these versions; and every third-party module is pinned by name where it is imported:
flexarm's packages in runtime, the tests, benchmarks and scripts in test.

Read from the installed metadata (importlib.metadata): run after scripts/setup.sh.
"""
from __future__ import annotations

import re
import tomllib
from collections import Counter
from dataclasses import dataclass
from functools import cache
from importlib import metadata
from importlib.util import find_spec
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from flexarm_test_support import source_imports

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / 'src'
SETS = {name: ROOT / 'requirements' / f'{name}.txt' for name in ('runtime', 'docs', 'test')}
# The graph's test tooling is a package of src/ but test code (it imports pytest): a runtime
# install leaves it out.
TEST_PACKAGES = ('flexarm_test_support',)
TEST_CODE = [ROOT / 'tests', ROOT / 'conftest.py', ROOT / 'benchmarks', ROOT / 'scripts',
             *SRC.glob('*/test'), *(SRC / p / p for p in TEST_PACKAGES)]
RUNTIME_CODE = [SRC / p.name / p.name for p in SRC.iterdir()
                if (SRC / p.name / p.name).is_dir() and p.name not in TEST_PACKAGES]
# Helpers imported by their file name (pytest.ini's pythonpath, a benchmark's own folder).
LOCAL = {p.stem for folder in TEST_CODE if folder.is_dir() for p in folder.rglob('*.py')}
# Distributions this repository builds (flexarm's packages, the interfaces of vendor/).
FIRST_PARTY = {canonicalize_name(tomllib.loads(p.read_text(encoding='utf-8'))['project']['name'])
               for p in [*SRC.glob('*/pyproject.toml'), *ROOT.glob('vendor/*/pyproject.toml')]}
TRANSITIVE_SECTION = '# --- transitive'


@dataclass(frozen=True)
class Pin:
    requirement: Requirement
    file: str
    direct: bool

    @property
    def name(self) -> str:
        return canonicalize_name(self.requirement.name)


def own_pins(path: Path) -> list[Pin]:
    """The pins written in one file, not those it includes."""
    pins, direct = [], True
    for line in path.read_text(encoding='utf-8').splitlines():
        direct = direct and not line.startswith(TRANSITIVE_SECTION)
        text = re.sub(r'(^|\s)#.*', '', line).strip()
        if text and not text.startswith('-r '):
            pins.append(Pin(Requirement(text), path.relative_to(ROOT).as_posix(), direct))
    return pins


def set_pins(path: Path) -> set[Pin]:
    """A file's pins and those of the files it includes (``-r``), as pip reads them."""
    pins = set(own_pins(path))
    for line in path.read_text(encoding='utf-8').splitlines():
        if line.startswith('-r '):
            pins |= set_pins(path.parent / line.split()[1])
    return pins


def all_files() -> list[Path]:
    return [ROOT / 'requirements.txt', *sorted((ROOT / 'requirements').glob('*.txt'))]


@cache
def module_distributions() -> dict[str, frozenset[str]]:
    """Top-level import name -> the distributions that install it: packages_distributions(),
    and the modules of wheels that keep their own site-packages (pin's under cmeel.prefix)."""
    found = {name: set(dists) for name, dists in metadata.packages_distributions().items()}
    for dist in metadata.distributions():
        for parts in (f.parts for f in dist.files or ()):
            if 'site-packages' in parts[1:-1]:
                top = parts[len(parts) - parts[::-1].index('site-packages')]
                found.setdefault(top.removesuffix('.py'), set()).add(dist.metadata['Name'])
    return {name: frozenset(map(canonicalize_name, dists)) for name, dists in found.items()}


def third_party_imports(folders: list[Path]) -> dict[str, set[str]]:
    """Top-level names imported under ``folders`` that are neither the standard library, nor
    flexarm, nor a local helper, each with the files importing it."""
    return source_imports.third_party_imports(folders, ROOT, LOCAL)


def is_ros_interface(module: str) -> bool:
    spec = find_spec(module)
    return any((Path(location) / kind).is_dir() for location in spec.submodule_search_locations
               or () for kind in ('msg', 'srv', 'action'))


def unprovided(imports: dict[str, set[str]], pins: set[Pin]) -> dict[str, list[str]]:
    """The imported modules no direct pin of ``pins`` provides. A ros-X module counts as pinned
    by name through ros-jazzy-X (the Jazzy metapackage pins exactly its release); a ROS
    interface package (msg/srv/action) through any ros-* pin of the set, as rclpy and
    common-interfaces bring them."""
    direct = {p.name for p in pins if p.direct}
    pinned = {p.name for p in pins}
    missing = {}
    for module, files in imports.items():
        dists = module_distributions().get(module, frozenset())
        if dists and dists <= FIRST_PARTY:
            continue
        if not any(d in direct or d.replace('ros-', 'ros-jazzy-', 1) in direct
                   or d.startswith('ros-') and d in pinned and is_ros_interface(module)
                   for d in dists):
            label = f'{module} (from {sorted(dists) or "no installed distribution"})'
            missing[label] = sorted(files)
    return missing


def closure(pins: set[Pin]) -> set[str]:
    """Every distribution the direct pins need, through the installed metadata."""
    needed: dict[str, set[str]] = {}
    todo = [p.requirement for p in pins if p.direct]
    while todo:
        requirement = todo.pop()
        name = canonicalize_name(requirement.name)
        if name in needed and set(requirement.extras) <= needed[name]:
            continue
        extras = needed.setdefault(name, set())
        extras |= requirement.extras
        try:
            requires = metadata.distribution(name).requires or ()
        except metadata.PackageNotFoundError:
            continue        # test_the_environment_holds_the_pinned_versions names it
        for text in requires:
            dependency = Requirement(text)
            if dependency.marker is None or any(dependency.marker.evaluate({'extra': extra})
                                                for extra in extras | {''}):
                todo.append(dependency)
    return set(needed)


def test_every_pin_is_exact():
    loose = [f'{p.file}: {p.requirement}' for path in all_files() for p in own_pins(path)
             if not (len(p.requirement.specifier) == 1 and p.requirement.url is None
                     and re.fullmatch(r'==[^=*]+', str(p.requirement.specifier)))]
    assert not loose, f'pin these to one version (==): {loose}'


def test_each_package_is_pinned_once():
    pins = [p for path in all_files() for p in own_pins(path)]
    twice = {name for name, count in Counter(p.name for p in pins).items() if count > 1}
    assert not twice, sorted(f'{p.file}: {p.requirement}' for p in pins if p.name in twice)


def test_the_environment_holds_the_pinned_versions():
    wrong = []
    for pin in set_pins(ROOT / 'requirements.txt'):
        try:
            version = metadata.distribution(pin.name).version
        except metadata.PackageNotFoundError:
            version = None
        if version is None or not pin.requirement.specifier.contains(version, prereleases=True):
            wrong.append(f'{pin.requirement} ({pin.file}): installed {version}')
    assert not wrong, f'run scripts/setup.sh: {sorted(wrong)}'


@pytest.mark.parametrize('name', sorted(SETS))
def test_a_set_pins_its_whole_closure_and_nothing_else(name):
    pins = set_pins(SETS[name])
    needed, pinned = closure(pins), {p.name for p in pins}
    assert not needed - pinned, (f'{name}: a fresh install would resolve these unpinned: '
                                 f'{sorted(needed - pinned)}')
    assert not pinned - needed, (f'{name}: nothing in the set needs {sorted(pinned - needed)} '
                                 '(move each to the set that does, or drop it)')


def test_the_runtime_set_pins_what_flexarm_imports():
    missing = unprovided(third_party_imports(RUNTIME_CODE), set_pins(SETS['runtime']))
    assert not missing, f'pin these by name in requirements/runtime.txt: {missing}'


def test_the_test_set_pins_what_the_tests_benchmarks_and_scripts_import():
    missing = unprovided(third_party_imports(TEST_CODE), set_pins(SETS['test']))
    assert not missing, f'pin these by name in requirements/ (test, runtime or docs): {missing}'


def test_the_interfaces_build_with_the_runtime_pins():
    """scripts/setup.sh builds them without build isolation, in the runtime environment."""
    def key(requirement: Requirement) -> tuple:
        return (canonicalize_name(requirement.name), frozenset(requirement.extras),
                requirement.specifier)

    runtime = {key(p.requirement) for p in set_pins(SETS['runtime'])}
    for path in [SRC / 'flexarm_msgs/pyproject.toml', *ROOT.glob('vendor/*/pyproject.toml')]:
        requires = tomllib.loads(path.read_text(encoding='utf-8'))['build-system']['requires']
        other = [r for r in requires if key(Requirement(r)) not in runtime]
        assert not other, f'{path.relative_to(ROOT)}: {other} differ from requirements/runtime.txt'
