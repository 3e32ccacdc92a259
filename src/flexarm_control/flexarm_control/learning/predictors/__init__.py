"""Deflection predictors Δ(θ) → (dx, dy, dφ) behind one interface (:class:`Predictor`).

``make_predictor(kind, settings)`` builds an unfitted one of ``KINDS``;
``load_predictor(path)`` reads any saved model (format: :mod:`.base`). The kinds: learned ones
on the normalised link angles — ``mlp`` (the paper's network), ``rbf``, ``gp`` (Gaussian
process, with a predictive std) — and ones that model the arm — ``kinematic`` (joint zero
offsets and link lengths by least squares: kinematic calibration), ``greybox`` (compliances ×
gravity moments through the kinematic chain, plus a GP on what is left) — and ``auto``, the
learner's default, which picks the best of kinematic, greybox and gp for the dataset by grouped
cross-validation (:mod:`.auto`).
"""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from flexarm_control.learning.predictors.auto import AutoPredictor
from flexarm_control.learning.predictors.base import FORMAT_VERSION, Predictor, read_model, restore
from flexarm_control.learning.predictors.gp import GpPredictor
from flexarm_control.learning.predictors.greybox import GreyboxPredictor
from flexarm_control.learning.predictors.kinematic import KinematicPredictor
from flexarm_control.learning.predictors.mlp import MlpPredictor
from flexarm_control.learning.predictors.rbf import RbfPredictor

_CLASSES: dict[str, type[Predictor]] = {
    cls.kind: cls for cls in (MlpPredictor, RbfPredictor, GpPredictor, KinematicPredictor,
                              GreyboxPredictor, AutoPredictor)}
KINDS = tuple(_CLASSES)

__all__ = ['FORMAT_VERSION', 'KINDS', 'AutoPredictor', 'GpPredictor', 'GreyboxPredictor',
           'KinematicPredictor', 'MlpPredictor', 'Predictor', 'RbfPredictor', 'load_predictor',
           'make_predictor']


def _class_of(kind: str) -> type[Predictor]:
    if kind not in _CLASSES:
        raise ValueError(f'unknown predictor kind {kind!r}; known kinds: {", ".join(KINDS)}')
    return _CLASSES[kind]


def make_predictor(kind: str, settings: Mapping[str, Any] | None = None) -> Predictor:
    """An unfitted predictor of ``kind``; ValueError for an unknown kind or bad settings."""
    return _class_of(kind)(settings)


def load_predictor(path: str | Path) -> Predictor:
    """The fitted predictor saved at ``path`` by :meth:`Predictor.save`.

    OSError if the file cannot be read; ValueError naming ``path`` for anything else that
    keeps it from being a usable model (empty, truncated, damaged, unknown kind, inconsistent).
    """
    metadata, state = read_model(path)
    try:
        return restore(_class_of(metadata['kind']), metadata, state)
    except ValueError as exc:
        raise ValueError(f'{path}: {exc}') from exc
