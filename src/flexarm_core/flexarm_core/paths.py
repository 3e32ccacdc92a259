"""Where flexarm keeps its files: ``config/`` of the source tree and the runtime directories
beside it, all git-ignored.

The tree is the clone this module runs from (pip's editable install, ``colcon build
--symlink-install``); a copying install (plain ``colcon build``) is not inside the clone, so
there ``FLEXARM_HOME`` names the clone, else the working directory is taken if it holds
``config/``. ``FLEXARM_STATE_DIR`` moves the runtime directories (data, models, runs,
results, bags, calibration) elsewhere while ``config/`` stays the tree's: the test suite points
it at a temporary folder, so no test reads or changes an operator's files.
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
STATE = (Path(os.environ['FLEXARM_STATE_DIR']).expanduser().resolve()
         if os.environ.get('FLEXARM_STATE_DIR') else REPO)
DATA_DIR = STATE / 'data'         # collected samples (JSON lines)
MODELS_DIR = STATE / 'models'     # trained models and current.json
RUNS_DIR = STATE / 'runs'         # per-graph logs and supervisor records
RESULTS_DIR = STATE / 'results'   # experiment and study outputs
BAGS_DIR = STATE / 'bags'         # MCAP bags
CALIBRATION_DIR = STATE / 'calibration'   # site calibrations (flexarm calibrate)


def repo_path(value: str) -> Path:
    """A configured runtime path (data, models, calibration): absolute, or relative to the
    runtime directories' root (the repository unless ``FLEXARM_STATE_DIR`` is set)."""
    path = Path(value).expanduser()
    return path if path.is_absolute() else STATE / path
