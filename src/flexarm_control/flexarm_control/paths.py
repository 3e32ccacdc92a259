"""Where flexarm keeps its files: ``config/`` of the source tree (editable install) and the
runtime directories beside it, all git-ignored."""
from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
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
