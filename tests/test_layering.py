"""The packages form layers: each imports only packages below it, and its package.xml and
pyproject.toml declare exactly the flexarm packages it imports (and every ROS package)."""
from __future__ import annotations

import ast
import re
import tomllib
from pathlib import Path
from xml.etree import ElementTree

import networkx
import pytest

SRC = Path(__file__).resolve().parents[1] / 'src'
# Lowest first: a package may import only the ones before it.
LAYERS = ['flexarm_msgs', 'flexarm_core', 'flexarm_description', 'flexarm_learning',
          'flexarm_deflection', 'flexarm_vision', 'flexarm_bridge', 'flexarm_sim',
          'flexarm_motion', 'flexarm_control', 'flexarm_bringup', 'flexarm_recording',
          'flexarm_viz', 'flexarm_cli', 'flexarm_test_support']
ROS = {'rclpy', 'std_msgs', 'sensor_msgs', 'geometry_msgs', 'rosgraph_msgs', 'builtin_interfaces',
       'action_msgs', 'unique_identifier_msgs', 'rcl_interfaces', 'diagnostic_msgs',
       'visualization_msgs', 'tf2_msgs', 'control_msgs'}


def imported(package: str) -> set[str]:
    """Top-level names the package's modules (not its tests) import."""
    names: set[str] = set()
    for path in (SRC / package / package).rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.Import):
                names.update(alias.name.split('.')[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split('.')[0])
    return names


def exec_depends(package: str) -> set[str]:
    root = ElementTree.parse(SRC / package / 'package.xml').getroot()
    return {e.text for e in root.iter('exec_depend')}


def project_depends(package: str) -> set[str]:
    with open(SRC / package / 'pyproject.toml', 'rb') as f:
        deps = tomllib.load(f)['project']['dependencies']
    return {re.split(r'[<>=\[ ]', d)[0].replace('-', '_') for d in deps}


@pytest.mark.parametrize('package', LAYERS[1:])
def test_a_package_imports_only_the_layers_below_it_and_declares_them(package):
    below = set(LAYERS[:LAYERS.index(package)])
    ours = {n for n in imported(package) if n.startswith('flexarm_')} - {package}
    assert ours <= below, f'{package} imports {sorted(ours - below)} from its own layer or above'
    assert {d for d in exec_depends(package) if d.startswith('flexarm_')} == ours
    assert project_depends(package) == ours
    missing = (imported(package) & ROS) - exec_depends(package)
    assert not missing, f'{package}/package.xml lacks {sorted(missing)}'


def test_every_package_is_in_a_layer():
    assert {p.name for p in SRC.iterdir() if (p / 'package.xml').exists()} == set(LAYERS)


def test_only_the_simulator_reads_its_truth():
    """config/sim.yaml defines the simulated real arm: no other package's code names it (the
    control side reads the nominal robot description, config/arm.yaml)."""
    readers = set()
    for package in LAYERS[1:]:
        for path in (SRC / package / package).rglob('*.py'):
            for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
                if isinstance(node, ast.Constant) and node.value in ('sim.yaml',
                                                                      'config/sim.yaml'):
                    readers.add(package)
    assert readers == {'flexarm_sim'}


@pytest.mark.parametrize('package', ['flexarm_control', 'flexarm_motion'])
def test_in_the_controller_only_its_ros_shell_imports_rclpy_or_messages(package):
    """The compensator's and learner's execution and the arm's motion policy are pure: the nodes,
    the arm interface and the client (``ros/``) are the only modules that import rclpy or any
    message package (they convert between messages and the pure cores' types)."""
    root = SRC / package / package
    shell = {path.relative_to(root).parts[0] for path in root.rglob('*.py')
             if _imports(path, ROS | {'flexarm_msgs'})}
    assert shell == {'ros'}


def _imports(path: Path, names: set[str]) -> bool:
    """Whether the module imports a top-level package of ``names``."""
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
        if isinstance(node, ast.Import) and any(a.name.split('.')[0] in names
                                                 for a in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and (node.module or '').split('.')[0] in names:
            return True
    return False


# Inside a package, sub-packages form layers too: each imports only the ones before it.
SUBLAYERS = {'flexarm_control': ['execution', 'ros'],
             'flexarm_motion': ['ros'],      # its flat modules are the pure policy below
             'flexarm_core': ['ros']}   # its modules outside ros/ are the pure bottom


def module_imports(package: str, src: Path = SRC) -> dict[str, set[str]]:
    """Every module of ``package`` (dotted name) and the modules of the package it imports,
    at the top or inside a function alike (either makes an import cycle): ``from a import b``
    names module ``a.b`` where that is one, else ``a``."""
    root = src / package
    modules = {'.'.join(path.relative_to(root).with_suffix('').parts).removesuffix('.__init__'):
               path for path in (root / package).rglob('*.py')}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        here = name if path.name == '__init__.py' else name.rpartition('.')[0]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.Import):
                targets.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ''
                if node.level:
                    parent = here.split('.')[:len(here.split('.')) - node.level + 1]
                    base = '.'.join(parent + ([base] if base else []))
                for alias in node.names:
                    targets.add(f'{base}.{alias.name}' if f'{base}.{alias.name}' in modules
                                else base)
        graph[name] = {t for t in targets if t in modules and t != name}
    return graph


def import_cycles(package: str, src: Path = SRC) -> list[list[str]]:
    """The groups of modules of ``package`` that import each other, directly or around."""
    graph = networkx.DiGraph([(a, b) for a, targets in module_imports(package, src).items()
                              for b in targets])
    return [sorted(c) for c in networkx.strongly_connected_components(graph) if len(c) > 1]


@pytest.mark.parametrize('package', LAYERS[1:])
def test_no_module_imports_itself_through_others(package):
    """No import cycle among a package's modules (a cycle works only by the order modules
    happen to be imported in, and ties what it joins into one)."""
    assert not import_cycles(package), f'import cycles in {package}'


def test_a_cycle_through_a_function_level_import_is_found(tmp_path):
    package = tmp_path / 'pkg' / 'pkg'
    (package / 'sub').mkdir(parents=True)
    (package / '__init__.py').write_text('')
    (package / 'sub' / '__init__.py').write_text('from pkg.sub.kinds import KIND\n')
    (package / 'sub' / 'kinds.py').write_text('KIND = 1\n\ndef fit():\n'
                                              '    from pkg.train import run\n')
    (package / 'train.py').write_text('from pkg.sub import KIND\n\nrun = KIND\n')
    assert import_cycles('pkg', tmp_path) == [['pkg.sub', 'pkg.sub.kinds', 'pkg.train']]


@pytest.mark.parametrize('package', sorted(SUBLAYERS))
def test_a_sub_package_imports_only_the_ones_below_it(package):
    """Inside a package the sub-packages are layers too (SUBLAYERS); a flat module is below
    them all."""
    order = SUBLAYERS[package]
    wrong = []
    for module, targets in module_imports(package).items():
        parts = module.split('.')
        if len(parts) < 2 or parts[1] == '__init__':
            continue
        above = order[order.index(parts[1]) + 1:] if parts[1] in order else order
        wrong += [f'{module} -> {target}' for target in targets
                  if len(target.split('.')) > 1 and target.split('.')[1] in above]
    assert not wrong, f'{package}: arrows up between sub-packages: {wrong}'


def test_in_the_core_only_its_ros_helpers_import_rclpy_or_messages():
    """flexarm_core is the pure bottom every package may use, with the rclpy helpers every node
    shares apart in ``flexarm_core/ros``."""
    package = SRC / 'flexarm_core' / 'flexarm_core'
    ros = {str(path.relative_to(package)) for path in package.rglob('*.py')
           if _imports(path, ROS | {'flexarm_msgs'})}
    assert ros and all(name.startswith('ros/') for name in ros), sorted(ros)


def public(package: str) -> set[str]:
    """The modules ``package`` names in its ``__init__``'s ``PUBLIC``."""
    tree = ast.parse((SRC / package / package / '__init__.py').read_text(encoding='utf-8'))
    for node in tree.body:
        if isinstance(node, ast.Assign) and [t.id for t in node.targets
                                             if isinstance(t, ast.Name)] == ['PUBLIC']:
            return set(ast.literal_eval(node.value))
    return set()


def imported_modules(folder: Path) -> set[tuple[str, str]]:
    """(file, flexarm module) of every import under ``folder`` that names a module of another
    flexarm package (``from a import b`` names ``a.b`` where that is a module)."""
    found = set()
    for path in folder.rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [f'{node.module}.{a.name}' for a in node.names]
                modules = [n for n in names if _is_module(n)] or [node.module]
            elif isinstance(node, ast.Import):
                modules = [a.name for a in node.names]
            else:
                continue
            found |= {(str(path.relative_to(SRC.parent)), m) for m in modules
                      if m.startswith('flexarm_') and m.split('.')[0] != 'flexarm_msgs'}
    return found


def _is_module(name: str) -> bool:
    path = SRC / name.split('.')[0] / Path(*name.split('.'))
    return path.with_suffix('.py').exists() or (path / '__init__.py').exists()


@pytest.mark.parametrize('package', LAYERS[1:])
def test_other_packages_import_only_what_a_package_makes_public(package):
    outside = {(f, m) for f, m in imported_modules(SRC / package / package)
               if m.split('.')[0] != package}
    wrong = sorted(f'{f}: {m}' for f, m in outside if m not in public(m.split('.')[0]))
    assert not wrong, f'imports of modules their package does not make public: {wrong}'


@pytest.mark.parametrize('package', LAYERS[1:])
def test_what_a_package_makes_public_exists(package):
    missing = sorted(m for m in public(package) if not _is_module(m))
    assert public(package) and not missing, missing


def test_no_module_imports_another_ones_private_names():
    """A leading underscore says "this module's own": whatever another module (a test or a
    benchmark too) needs is public."""
    root = SRC.parent
    paths = [*SRC.glob('*/*/**/*.py'), *SRC.glob('*/test/*.py'), *root.glob('tests/**/*.py'),
             *root.glob('benchmarks/*.py'), root / 'conftest.py']
    private = sorted(
        f'{path.relative_to(root)}: {node.module}.{alias.name}'
        for path in paths for node in ast.walk(ast.parse(path.read_text(encoding='utf-8')))
        if isinstance(node, ast.ImportFrom) and (node.module or '').startswith('flexarm_')
        for alias in node.names if alias.name.startswith('_') and not alias.name.startswith('__'))
    assert not private, private


@pytest.mark.parametrize('package', LAYERS[1:])
def test_a_packages_tests_import_it_and_what_lies_below_only(package):
    """A package's tests run with it and the packages below (``colcon test --packages-select``
    works); tests across packages, of the graph or of one package against another's, live in
    tests/."""
    below = set(LAYERS[:LAYERS.index(package) + 1])
    above = sorted({f'{f}: {m}' for f, m in imported_modules(SRC / package / 'test')
                    if m.split('.')[0] not in below})
    assert not above, above
