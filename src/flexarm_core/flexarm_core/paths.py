"""Where flexarm keeps its files: ``config/`` and the runtime directories.

flexarm_core installs ``config/`` (to ``share/flexarm_core/config``): it is the bottom of the
stack and every package reads its parameters through it (:mod:`flexarm_core.params`), so a node
finds them with only its own dependencies installed; installed by flexarm_bringup, the top, a
lone ``sim_node`` would need the whole graph. ``config/`` is taken from, in order:

1. ``$FLEXARM_HOME/config`` when ``FLEXARM_HOME`` names a clone;
2. the source tree this module runs from (pip's editable install, ``colcon build
   --symlink-install``), so edits take effect without a rebuild;
3. ``share/flexarm_core/config`` of a copying install (plain ``colcon build``, a binary
   package), found through the ament index that the workspace's setup script extends.

A site's own settings live outside the clone, in a site folder (``FLEXARM_SITE``, or
``flexarm --site DIR``; ``flexarm site init DIR`` writes a starting point): its ``config/``
holds params files that layer over the clone's of the same name, parameter by parameter, and a
``graph.yaml`` whose robot entries and settings replace the clone's of the same name
(:mod:`flexarm_core.params`). Nothing in the clone is edited for a real arm.

The runtime directories (data, models, runs, results, bags, calibration) are git-ignored folders
beside ``config/`` in the clone, in the site folder when there is one; an install outside a
clone makes them in the working directory. ``FLEXARM_STATE_DIR`` moves them elsewhere: the test
suite points it at a temporary folder, so no test reads or changes an operator's files.
"""
from __future__ import annotations

import os
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[3]   # the clone, when this module runs from it


def _clone() -> Path | None:
    """``FLEXARM_HOME``, else the source tree if this module runs from one."""
    if os.environ.get('FLEXARM_HOME'):
        return Path(os.environ['FLEXARM_HOME']).expanduser().resolve()
    return SOURCE if (SOURCE / 'config').is_dir() else None


def _installed_config() -> Path:
    """``config/`` in flexarm_core's share directory (ament_index_python is imported only here:
    a clone, as in pip's venv, has no ament index to search)."""
    from ament_index_python.packages import get_package_share_directory
    try:
        return Path(get_package_share_directory('flexarm_core')) / 'config'
    except (LookupError, OSError) as error:     # not in the index, or no AMENT_PREFIX_PATH
        raise RuntimeError(
            'no flexarm config/: flexarm_core runs from no clone and is not in the ament index '
            f'({error!s}); source the workspace (install/setup.sh) or set FLEXARM_HOME to a '
            'clone') from error


SITE_ENV = 'FLEXARM_SITE'
CLONE = _clone()
CONFIG_DIR = CLONE / 'config' if CLONE else _installed_config()
SITE = (Path(os.environ[SITE_ENV]).expanduser().resolve() if os.environ.get(SITE_ENV)
        else None)
SITE_CONFIG_DIR = SITE / 'config' if SITE else None     # the site's layer over CONFIG_DIR
STATE = (Path(os.environ['FLEXARM_STATE_DIR']).expanduser().resolve()
         if os.environ.get('FLEXARM_STATE_DIR') else SITE or CLONE or Path.cwd())
DATA_DIR = STATE / 'data'         # collected samples (JSON lines)
MODELS_DIR = STATE / 'models'     # trained models and current.json
RUNS_DIR = STATE / 'runs'         # per-graph logs and supervisor records
RESULTS_DIR = STATE / 'results'   # experiment and study outputs
BAGS_DIR = STATE / 'bags'         # MCAP bags
CALIBRATION_DIR = STATE / 'calibration'   # site calibrations (flexarm calibrate)


def repo_path(value: str) -> Path:
    """A configured runtime path (data, models, calibration): absolute, or relative to the
    runtime directories' root (the clone, unless ``FLEXARM_STATE_DIR`` is set)."""
    path = Path(value).expanduser()
    return path if path.is_absolute() else STATE / path
