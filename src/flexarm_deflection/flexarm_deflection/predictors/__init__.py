"""Deflection predictors Δ(θ) → (dx, dy, dφ) behind one interface (:class:`Predictor`).

``make_predictor(kind, settings)`` builds an unfitted one of ``KINDS`` (file format:
:mod:`.base`). The kinds: learned ones on the normalised link angles — ``mlp`` (the paper's
network), ``rbf``, ``gp`` (Gaussian process, with a predictive std) — and ones that model the
arm — ``kinematic`` (joint zero offsets and link lengths by least squares: kinematic
calibration), ``greybox`` (compliances × gravity moments through the kinematic chain, plus a GP
on what is left). Choosing among them for a dataset is model selection, above them
(:mod:`~flexarm_deflection.selection`); every kind by name, ``auto`` included, and the
loading of any saved model: :mod:`~flexarm_deflection.models`.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from flexarm_deflection.predictors.base import FORMAT_VERSION, Predictor, restore
from flexarm_deflection.predictors.gp import GpPredictor
from flexarm_deflection.predictors.greybox import GreyboxPredictor
from flexarm_deflection.predictors.kinematic import KinematicPredictor
from flexarm_deflection.predictors.mlp import MlpPredictor
from flexarm_deflection.predictors.rbf import RbfPredictor

_CLASSES: dict[str, type[Predictor]] = {
    cls.kind: cls for cls in (MlpPredictor, RbfPredictor, GpPredictor, KinematicPredictor,
                              GreyboxPredictor)}
KINDS = tuple(_CLASSES)

__all__ = ['FORMAT_VERSION', 'KINDS', 'GpPredictor', 'GreyboxPredictor', 'KinematicPredictor',
           'MlpPredictor', 'Predictor', 'RbfPredictor', 'make_predictor', 'predictor_class',
           'restore']


def predictor_class(kind: str) -> type[Predictor]:
    """The class of ``kind``; ValueError naming the known kinds for any other."""
    if kind not in _CLASSES:
        raise ValueError(f'unknown predictor kind {kind!r}; known kinds: {", ".join(KINDS)}')
    return _CLASSES[kind]


def make_predictor(kind: str, settings: Mapping[str, Any] | None = None) -> Predictor:
    """An unfitted predictor of ``kind``; ValueError for an unknown kind or bad settings."""
    return predictor_class(kind)(settings)
