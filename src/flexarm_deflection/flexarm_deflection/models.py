"""Every kind of deflection model by name: the predictors and ``auto``, model selection over
them (:class:`~flexarm_deflection.selection.AutoPredictor`). What the learner makes and
the compensator loads; ``auto`` is the learner's default.
"""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from flexarm_deflection import predictors
from flexarm_deflection.predictors import Predictor, restore
from flexarm_deflection.predictors.base import read_model
from flexarm_deflection.selection import AutoPredictor

KINDS = (*predictors.KINDS, AutoPredictor.kind)


def model_class(kind: str) -> type[Predictor]:
    """The class of ``kind``; ValueError naming every known kind for any other."""
    if kind == AutoPredictor.kind:
        return AutoPredictor
    if kind not in predictors.KINDS:
        raise ValueError(f'unknown predictor kind {kind!r}; known kinds: {", ".join(KINDS)}')
    return predictors.predictor_class(kind)


def make_model(kind: str, settings: Mapping[str, Any] | None = None) -> Predictor:
    """An unfitted model of ``kind``; ValueError for an unknown kind or bad settings."""
    return model_class(kind)(settings)


def load_model(path: str | Path) -> Predictor:
    """The fitted model saved at ``path`` by :meth:`Predictor.save`.

    OSError if the file cannot be read; ValueError naming ``path`` for anything else that
    keeps it from being a usable model (empty, truncated, damaged, unknown kind, inconsistent).
    """
    metadata, state = read_model(path)
    try:
        return restore(model_class(metadata['kind']), metadata, state)
    except ValueError as exc:
        raise ValueError(f'{path}: {exc}') from exc


def model_metadata(path: str | Path) -> dict[str, Any]:
    """What a saved model says of itself (kind, version, samples, metrics, ...), without
    restoring it: OSError if the file cannot be read, ValueError for one that is no model."""
    return read_model(path)[0]
