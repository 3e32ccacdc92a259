"""What a newly declared payload does to the model's error bounds, said when it is declared
(pure; what the learner logs and ``flexarm payload KG`` says).

A model trained at some payloads and asked at another states a wider bound there: the
grey-box's masses' prior (:meth:`~flexarm_deflection.predictors.Predictor.prior_std`),
a model with the payload input its own std. Per working region, the median 95 % position
bound over a grid of its poses, at the nearest trained payload and at the one declared, and
what brings it back: a refresh at this payload, which measures a few samples carrying it and
trains the model on both payloads (:func:`needs_retraining`). A model that neither takes the
payload as an input nor models it cannot predict there at all: PREDICTIVE is refused until
then.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.regions import Region
from flexarm_deflection.predictors import Predictor
from flexarm_deflection.predictors.base import PAYLOAD_TOLERANCE
from flexarm_deflection.sampling import sample_poses

POSES = 16       # a region's Sobol poses the median bound is taken over


def needs_retraining(trained: Sequence[float], payload: float) -> bool:
    """Whether ``payload`` [kg] is none of the ``trained`` ones (a refresh then trains on
    both; known trained payloads only)."""
    return bool(trained) and all(abs(p - payload) > PAYLOAD_TOLERANCE for p in trained)


def bound_report(predictor: Predictor, regions: Mapping[str, Region], geometry: ArmGeometry,
                 trained: Sequence[float], payload: float) -> str:
    """How the bounds grew at ``payload`` [kg] and what brings them back ('' when it is a
    trained one)."""
    if not needs_retraining(trained, payload):
        return ''
    nearest = min(trained, key=lambda p: abs(p - payload))
    if not predictor.carries_payload:
        return (f'the model, trained at {_listed(trained)} kg, cannot predict at {payload:g} kg: '
                f'PREDICTIVE goals are refused until `flexarm refresh` measures samples '
                f'carrying it and trains on both payloads')
    parts = []
    for name, region in regions.items():
        joints = sample_poses(geometry, region, POSES, 'sobol', 0)[1]
        before, after = (float(np.median(predictor.error_bound(joints, p)[:, 0]))
                         for p in (nearest, payload))
        parts.append(f'region {name} {before * 1e3:.3f} -> {after * 1e3:.3f} mm')
    return (f'the model was trained at {_listed(trained)} kg: at {payload:g} kg its 95 % '
            f'position bounds grew ({"; ".join(parts)}; median over each region); '
            '`flexarm refresh --region NAME` measures samples carrying it and trains on both '
            'payloads, which brings them back')


def _listed(payloads: Sequence[float]) -> str:
    return ', '.join(f'{p:g}' for p in sorted(payloads))
