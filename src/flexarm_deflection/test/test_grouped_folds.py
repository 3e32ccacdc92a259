"""The cross-validation's folds: whole poses held out together, the same folds scikit-learn's
GroupKFold(shuffle=True) makes for a seed (the figures measured with it hold), and training
imports no scikit-learn."""
import subprocess
import sys

import numpy as np
import pytest

from flexarm_deflection.cross_validation import grouped_folds


@pytest.mark.parametrize('seed', range(4))
def test_folds_are_scikit_learns_and_keep_each_group_whole(seed):
    from sklearn.model_selection import GroupKFold

    groups = np.random.default_rng(seed).integers(0, 17, 60)
    folds = grouped_folds(groups, 5, seed)
    reference = [test for _, test in GroupKFold(5, shuffle=True, random_state=seed).split(
        np.zeros(len(groups)), groups=groups)]
    assert all(np.array_equal(a, b) for a, b in zip(folds, reference, strict=True))
    assert np.array_equal(np.sort(np.concatenate(folds)), np.arange(len(groups)))
    for test in folds:
        assert not set(groups[test]) & set(np.delete(groups, test))


def test_a_training_imports_no_scikit_learn():
    code = ('import sys, numpy as np\n'
            'from flexarm_deflection.selection import fit_robust\n'
            'rng = np.random.default_rng(0)\n'
            'q = np.column_stack([rng.uniform(-1, 1, 30), rng.uniform(0.2, 0.8, 30),\n'
            '                     rng.uniform(-1, 1, 30), rng.uniform(-1, 1, 30)])\n'
            'fit_robust("rbf", {}, q, np.sin(q[:, :3]) * 1e-3, folds=5)\n'
            'assert "sklearn" not in sys.modules, "scikit-learn imported"\n')
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
