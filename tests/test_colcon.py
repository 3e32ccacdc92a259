"""src/ is a ROS 2 workspace too (docs/building.md "Building with colcon"): colcon finds
every package (flexarm_msgs as ament_cmake, the others as ament_python), ``colcon build``
builds the Python packages into a temporary workspace, installs each node executable under
``lib/<package>/`` (where ``ros2 run`` looks), registers each package in the ament index with
its package.xml, copies config/ to flexarm_core's share directory, and the install space
imports as ``install/setup.sh`` sets it up, finding config/ there (no FLEXARM_HOME, no clone
around it).

colcon runs once for the module, from the venv, with the venv's bin first on PATH and nothing of
an outer ROS environment. flexarm_msgs is left out of the build (``--packages-ignore``): its
CMakeLists is built by every set-up (scripts/setup.sh: pip and scikit-build-core run the same
ament_cmake and rosidl build into the venv), which is the underlay the workspace finds it in.
Building it again here cost 40 of the suite's 470 CPU-seconds and tested nothing new.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.colcon, pytest.mark.timeout(300), pytest.mark.duration(20)]
SRC = Path(__file__).resolve().parents[1] / 'src'
CONFIG = SRC.parent / 'config'
PACKAGES = sorted(p.name for p in SRC.iterdir() if (p / 'package.xml').exists())
MSGS = 'flexarm_msgs'                     # built by scripts/setup.sh (module docstring)
PYTHON_PACKAGES = [p for p in PACKAGES if p != MSGS]
# Executables that are not `<package>/<name>_node.py` modules with a main().
OTHER_EXECUTABLES = {'flexarm_sim': {'fake_controller'}, 'flexarm_cli': {'flexarm'},
                     'flexarm_test_support': {'ros2_control_standin'}}
OUTER_ROS = ('AMENT_PREFIX_PATH', 'CMAKE_PREFIX_PATH', 'COLCON_PREFIX_PATH', 'PYTHONPATH',
             'LD_LIBRARY_PATH', 'VIRTUAL_ENV', '_ROS_WHEELS_BOOTSTRAP_COMPLETE',
             'COLCON_DEFAULTS_FILE')


def expected_executables(package: str) -> set[str]:
    """The package's node modules (at any depth) with a main(), and its other executables."""
    nodes = {path.stem for path in (SRC / package / package).rglob('*_node.py')
             if re.search(r'^def main\(', path.read_text(encoding='utf-8'), re.MULTILINE)}
    return nodes | OTHER_EXECUTABLES.get(package, set())


def workspace_env(root: Path) -> dict[str, str]:
    """This environment less any outer ROS/colcon setup and FLEXARM_HOME (the install finds
    config/ itself), with the venv's bin first on PATH."""
    env = {k: v for k, v in os.environ.items() if k not in (*OUTER_ROS, 'FLEXARM_HOME')}
    env['PATH'] = f'{Path(sys.executable).parent}{os.pathsep}{env["PATH"]}'
    env['COLCON_HOME'] = str(root / 'colcon_home')    # no user defaults (e.g. symlink-install)
    return env


@pytest.fixture(scope='module')
def workspace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The root of a workspace that colcon built src/ into (build/, install/, log/)."""
    root = tmp_path_factory.mktemp('colcon')
    colcon = Path(sys.executable).parent / 'colcon'
    run = subprocess.run(
        [str(colcon), '--log-base', str(root / 'log'), 'build', '--base-paths', str(SRC),
         '--build-base', str(root / 'build'), '--install-base', str(root / 'install'),
         '--packages-ignore', MSGS,
         '--event-handlers', 'console_direct-', 'desktop_notification-', 'terminal_title-'],
        cwd=root, env=workspace_env(root), capture_output=True, text=True, timeout=840)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-4000:]
    return root


def test_colcon_finds_every_package_and_builds_the_python_ones(workspace):
    listed = subprocess.run(
        [str(Path(sys.executable).parent / 'colcon'), '--log-base', os.devnull, 'list',
         '--base-paths', str(SRC)], env=workspace_env(workspace), capture_output=True,
        text=True, timeout=60)
    kinds = dict(line.split()[::2] for line in listed.stdout.splitlines())
    assert kinds == {p: '(ros.ament_cmake)' if p == MSGS else '(ros.ament_python)'
                     for p in PACKAGES}, listed.stdout + listed.stderr
    built = {p.name for p in (workspace / 'install').iterdir() if p.is_dir()}
    assert built == set(PYTHON_PACKAGES)


@pytest.mark.parametrize('package', PYTHON_PACKAGES)
def test_a_package_is_in_the_ament_index_with_its_manifest(workspace, package):
    prefix = workspace / 'install' / package
    assert (prefix / 'share/ament_index/resource_index/packages' / package).is_file()
    manifest = prefix / 'share' / package / 'package.xml'
    assert manifest.read_bytes() == (SRC / package / 'package.xml').read_bytes()


LIBRARIES = {'flexarm_core', 'flexarm_learning', 'flexarm_deflection',    # no executable of
             'flexarm_bringup'}                                        # their own


@pytest.mark.parametrize('package', [p for p in PYTHON_PACKAGES if p not in LIBRARIES])
def test_node_executables_are_installed_under_lib_package(workspace, package):
    expected = expected_executables(package)
    assert expected, f'{package} has no executable to install'
    lib = workspace / 'install' / package / 'lib' / package
    installed = {p.name for p in lib.iterdir() if p.is_file() and os.access(p, os.X_OK)}
    assert installed == expected


def test_the_install_space_imports_and_runs_as_its_setup_script_sets_it_up(workspace):
    install = workspace / 'install'
    site = Path('lib', f'python{sys.version_info.major}.{sys.version_info.minor}',
                'site-packages')
    code = ('import flexarm_cli, flexarm_control.execution.compensator, flexarm_msgs.msg\n'
            'from rclpy.serialization import serialize_message\n'
            'assert serialize_message(flexarm_msgs.msg.PlanarPose(x=1.5))\n'
            'for m in (flexarm_msgs, flexarm_control, flexarm_cli):\n'
            '    print(m.__file__)\n'
            'from flexarm_core.paths import CONFIG_DIR\n'
            'print(CONFIG_DIR)\n')
    flexarm = install / 'flexarm_cli/lib/flexarm_cli/flexarm'
    run = subprocess.run(
        ['sh', '-c', f'. "{install}/setup.sh" && python -c "$0" && "{flexarm}" --help', code],
        cwd=workspace, env=workspace_env(workspace), capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stdout + run.stderr
    lines = run.stdout.splitlines()
    underlay = Path(sys.prefix) / site / MSGS / '__init__.py'      # the venv: scripts/setup.sh
    assert lines[:3] == [str(underlay)] + [str(install / p / site / p / '__init__.py')
                                           for p in ('flexarm_control', 'flexarm_cli')]
    assert lines[3] == str(install / 'flexarm_core/share/flexarm_core/config')
    assert lines[4].startswith('usage: flexarm')


def test_config_is_installed_as_copies_of_every_file(workspace):
    def files(root: Path) -> dict[Path, bytes]:
        return {p.relative_to(root): p.read_bytes() for p in root.rglob('*') if p.is_file()}

    share = workspace / 'install/flexarm_core/share/flexarm_core/config'
    assert not [p for p in share.rglob('*') if p.is_symlink()]
    assert files(share) == files(CONFIG)
