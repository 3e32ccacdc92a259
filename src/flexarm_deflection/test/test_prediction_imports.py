"""Neither the compensator and learner node modules nor loading a model and predicting with
it import torch or scikit-learn: they cost a node's start-up ~1.6 s and ~0.5 s of a 2-core
machine. Only fitting does (the MLP trains with torch), in the learner's training worker. The
control nodes import no scipy until they fit or predict (~0.3 s), and the kinematic and MLP
kinds predict, bound and judge their distance from the data without it (scipy.spatial alone
cost a compensator 0.35 s of CPU at its first goal). Checked in a fresh interpreter, as the
other tests import all of them.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from flexarm_deflection.models import KINDS, make_model

pytestmark = pytest.mark.duration(25)

# Kinds that predict, bound and judge their data distance with numpy alone (checked first)
SCIPY_FREE = ('kinematic', 'mlp')
CHECK = '''
import sys

import numpy as np

import flexarm_control.ros.compensator_node
import flexarm_control.ros.learner_node
from flexarm_deflection.models import load_model

assert not {'torch', 'sklearn'} & set(sys.modules), 'imported by a control node module'
assert 'scipy' not in sys.modules, 'imported by a control node before it fits or predicts'
joints = np.array([0.1, 0.6, -0.3, 0.2])
for path in sys.argv[2:]:
    predictor = load_model(path)
    assert predictor.predict(joints).shape == (3,)
    predictor.data_distance(joints), predictor.position_std(joints)
    predictor.deflection_std(joints)
    assert not {'torch', 'sklearn'} & set(sys.modules), f'imported to predict with {path}'
    if predictor.kind in sys.argv[1].split(','):
        assert 'scipy' not in sys.modules, f'imported to predict with {path}'
'''


def test_loading_and_predicting_do_not_import_torch_or_sklearn(tmp_path: Path) -> None:
    joints = np.random.default_rng(0).uniform([-0.5, 0.3, -1.5, -1.0], [0.5, 0.8, 0.5, 1.0],
                                              (20, 4))
    deflections = np.column_stack([np.sin(joints[:, 0]), joints[:, 1] ** 2, joints[:, 3]])
    settings = {'mlp': {'members': 2, 'max_iterations': 50}, 'gp': {'restarts': 0}}
    paths = []
    for kind in sorted(KINDS, key=lambda kind: kind not in SCIPY_FREE):
        paths.append(str(tmp_path / f'{kind}.npz'))
        make_model(kind, settings.get(kind)).fit(joints, deflections).save(paths[-1])
    run = subprocess.run([sys.executable, '-c', CHECK, ','.join(SCIPY_FREE), *paths],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr

