"""Where flexarm keeps its files: ``config/`` of the source tree and the runtime directories
beside it, all git-ignored.

The tree is the clone this module runs from (pip's editable install, ``colcon build
--symlink-install``); a copying install (plain ``colcon build``) is not inside the clone, so
there ``FLEXARM_HOME`` names the clone, else the working directory is taken if it holds
``config/``.
"""
from __future__ import annotations

import os
from pathlib import Path


def _repo() -> Path:
    if os.environ.get('FLEXARM_HOME'):
        return Path(os.environ['FLEXARM_HOME']).expanduser().resolve()
    source = Path(__file__).resolve().parents[3]
    if (source / 'config').is_dir() or not (Path.cwd() / 'config').is_dir():
        return source
    return Path.cwd()


REPO = _repo()
CONFIG_DIR = REPO / 'config'
DATA_DIR = REPO / 'data'         # collected samples (JSON lines)
MODELS_DIR = REPO / 'models'     # trained models and current.json
RUNS_DIR = REPO / 'runs'         # per-graph logs and supervisor records
RESULTS_DIR = REPO / 'results'   # experiment and study outputs
BAGS_DIR = REPO / 'bags'         # MCAP bags
CALIBRATION_DIR = REPO / 'calibration'   # site calibrations (flexarm calibrate)


def repo_path(value: str) -> Path:
    """A configured path: absolute, or relative to the repository."""
    path = Path(value).expanduser()
    return path if path.is_absolute() else REPO / path
