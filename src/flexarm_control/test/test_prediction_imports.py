"""Prediction never imports torch (nor the compensator node scikit-learn): they cost a node's
start-up ~0.7 s and ~0.5 s of a 2-core machine. Checked in a fresh interpreter, as the other
tests import both. The MLP predicts in numpy with the activations it trains with in torch.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from flexarm_control.predictors import KINDS, make_predictor, mlp, mlp_training

CHECK = '''
import sys

import numpy as np

import flexarm_control.compensator_node
from flexarm_control.predictors import load_predictor

assert not {'torch', 'sklearn'} & set(sys.modules), 'imported by the compensator node'
joints = np.array([0.1, 0.6, -0.3, 0.2])
for path in sys.argv[1:]:
    predictor = load_predictor(path)
    assert predictor.predict(joints).shape == (3,)
    predictor.data_distance(joints), predictor.position_std(joints)
    assert 'torch' not in sys.modules, f'imported to predict with {path}'
'''


def test_loading_and_predicting_do_not_import_torch(tmp_path: Path) -> None:
    joints = np.random.default_rng(0).uniform([-0.5, 0.3, -1.5, -1.0], [0.5, 0.8, 0.5, 1.0],
                                              (20, 4))
    deflections = np.column_stack([np.sin(joints[:, 0]), joints[:, 1] ** 2, joints[:, 3]])
    settings = {'mlp': {'restarts': 1, 'max_iterations': 50}, 'gp': {'restarts': 0}}
    paths = []
    for kind in KINDS:
        paths.append(str(tmp_path / f'{kind}.npz'))
        make_predictor(kind, settings.get(kind)).fit(joints, deflections).save(paths[-1])
    run = subprocess.run([sys.executable, '-c', CHECK, *paths], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr


def test_the_mlp_predicts_in_numpy_what_it_trained_in_torch() -> None:
    import torch

    assert mlp.ACTIVATIONS.keys() == mlp_training.ACTIVATIONS.keys()
    x = np.linspace(-3.0, 3.0, 13)
    for name, activation in mlp.ACTIVATIONS.items():
        np.testing.assert_allclose(activation(x), mlp_training.ACTIVATIONS[name](
            torch.from_numpy(x)).numpy(), rtol=1e-12, atol=1e-15)
