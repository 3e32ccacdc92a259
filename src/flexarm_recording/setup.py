"""colcon's ament_python build runs setup.py: setuptools reads everything from pyproject.toml
(metadata, entry points, data files), the one source of truth. `colcon build --symlink-install`
runs a link to this file in its build directory, where pyproject.toml is missing: link it too."""
from pathlib import Path

from setuptools import setup

if not Path('pyproject.toml').exists():
    Path('pyproject.toml').symlink_to(Path(__file__).resolve().with_name('pyproject.toml'))
setup()
