"""``rosdep install --from-paths src --ignore-src`` resolves on a ROS 2 Jazzy system and leaves
nothing out: every key of every package.xml is a flexarm package, a key rosdistro has for Jazzy
(rosdep/jazzy-keys.txt, each checked once against rosdistro) or one of our rules
(rosdep/flexarm.yaml); and every package declares each third-party module it imports.

No network: rosdistro was read once to write jazzy-keys.txt; this keeps the package.xml files
to that list, so a key that is no rosdep key (a guess such as ``python3-mcap``) fails here
rather than on the first machine that runs rosdep.
"""
from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree

import pytest
import yaml

from flexarm_test_support import source_imports

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / 'src'
PACKAGES = sorted(p.name for p in SRC.iterdir() if (p / 'package.xml').exists())
DEPENDS = ('depend', 'build_depend', 'exec_depend', 'test_depend', 'buildtool_depend')
RUN_DEPENDS = ('depend', 'exec_depend')
# Import names that differ from their rosdep key; a ROS package imports as its own name.
KEYS = {'cv2': 'python3-opencv', 'foxglove': 'python3-foxglove-sdk-pip',
        'matplotlib': 'python3-matplotlib', 'mcap': 'python3-mcap-pip',
        'mcap_ros2': 'mcap-ros2-support', 'numpy': 'python3-numpy', 'psutil': 'python3-psutil',
        'pytest': 'python3-pytest', 'scipy': 'python3-scipy', 'sklearn': 'python3-sklearn',
        'threadpoolctl': 'python3-threadpoolctl', 'torch': 'python3-torch',
        'tqdm': 'python3-tqdm', 'yaml': 'python3-yaml', 'rosbags': 'python3-rosbags-pip',
        'urdf_parser_py': 'urdfdom_py'}
# A package's own test helpers, importable by name (pytest.ini puts their folder on the path).
TEST_HELPERS = {p.stem for p in SRC.glob('*/test/*.py') if not p.stem.startswith('test_')}


def jazzy_keys() -> set[str]:
    lines = (ROOT / 'rosdep/jazzy-keys.txt').read_text(encoding='utf-8').splitlines()
    return {line.split('#')[0].split()[0] for line in lines if line.split('#')[0].strip()}


def our_rules() -> dict[str, dict]:
    return yaml.safe_load((ROOT / 'rosdep/flexarm.yaml').read_text(encoding='utf-8'))


def declared(package: str, tags: tuple[str, ...] = DEPENDS) -> set[str]:
    root = ElementTree.parse(SRC / package / 'package.xml').getroot()
    return {e.text.strip() for tag in tags for e in root.iter(tag)}


def third_party_imports(folder: Path) -> dict[str, set[str]]:
    """Top-level names that the modules under ``folder`` import and that are neither the
    standard library nor flexarm, each with the files importing it."""
    return source_imports.third_party_imports([folder], SRC)


def undeclared(imports: dict[str, set[str]], keys: set[str]) -> dict[str, list[str]]:
    return {f'{name} (key {KEYS.get(name, name)})': sorted(files)
            for name, files in imports.items() if KEYS.get(name, name) not in keys}


@pytest.mark.parametrize('package', PACKAGES)
def test_every_key_is_ours_or_resolves_for_jazzy(package):
    unknown = declared(package) - set(PACKAGES) - jazzy_keys() - set(our_rules())
    assert not unknown, (f'{package}/package.xml: {sorted(unknown)} are no rosdep keys (check '
                         'rosdistro, then add them to rosdep/jazzy-keys.txt or flexarm.yaml)')


@pytest.mark.parametrize('package', PACKAGES)
def test_a_package_declares_what_its_modules_import(package):
    missing = undeclared(third_party_imports(SRC / package / package),
                         declared(package, RUN_DEPENDS))
    assert not missing, f'{package}/package.xml lacks an exec_depend for {missing}'


@pytest.mark.parametrize('package', PACKAGES)
def test_a_package_declares_what_its_tests_import(package):
    """A test's flexarm imports are left out: a test_depend on a package above would close a
    dependency cycle, and the tests run from the clone, where every package is."""
    imports = third_party_imports(SRC / package / 'test')
    missing = undeclared({n: f for n, f in imports.items() if n not in TEST_HELPERS},
                         declared(package))
    assert not missing, f'{package}/package.xml lacks a test_depend for {missing}'


def test_every_listed_key_and_rule_is_used_and_ours_shadow_none_of_rosdistro():
    used = set().union(*(declared(p) for p in PACKAGES))
    assert jazzy_keys() <= used, f'unused in jazzy-keys.txt: {sorted(jazzy_keys() - used)}'
    assert set(our_rules()) <= used, f'unused in flexarm.yaml: {sorted(set(our_rules()) - used)}'
    assert not jazzy_keys() & set(our_rules())


@pytest.mark.parametrize('key', sorted(our_rules()))
def test_each_rule_installs_on_ubuntu_and_debian(key):
    rule = our_rules()[key]
    for os_name in ('ubuntu', 'debian'):
        entry = rule[os_name]      # an apt list, or {'pip': {'packages': [...]}}
        packages = entry['pip']['packages'] if isinstance(entry, dict) else entry
        assert packages and all(isinstance(p, str) for p in packages), (key, os_name)
