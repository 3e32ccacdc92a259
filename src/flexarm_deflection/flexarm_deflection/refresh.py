"""A model refresh: where to measure, and the refreshed model (pure).

:func:`refresh_poses` plans the few learning poses of a refresh: half of them (rounded up)
where the model health saw its largest residuals (:meth:`ModelHealth.worst_joints`), the rest
space-filling over the stale region grown by the coverage margin, so the correction is pinned
down where goals missed and across the region. :func:`refreshed` fits the
:class:`~flexarm_deflection.drift_correction.Correction` to the samples taken there and
returns the corrected model under a new version, with its bound recalibrated: the bound the
model was trained with knows nothing of the change, and the correction leaves some of it (an
8-sample refresh after an undeclared load left up to 0.28 mm where the old bound stated
0.08 mm). The correction's own uncertainty (its parameters' covariance,
:meth:`~flexarm_deflection.drift_correction.Correction.std`) is added to the model's
bound, scaled on the refresh's samples: each one's residual under the correction fitted on
the others (leave-one-out) against the std that correction stated there, the position's and
the angle's scale apart (the correction's turn is the less certain: its held-out angle
residuals ran 2-3 times its std, its position ones 0.2-1.3 times).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Collection, Sequence
from typing import Any

import numpy as np

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.regions import Region
from flexarm_deflection.drift_correction import fit_correction, left_out
from flexarm_deflection.error_bound import split
from flexarm_deflection.predictors import Predictor
from flexarm_deflection.sampling import sample_poses


def refresh_regions(region: str, force: bool, health: Sequence[Any], known: Collection[str],
                    stale_residual: float) -> list[str]:
    """The regions a refresh measures: ``region`` if given, else those the model health
    (``health``: its regions, each with name, stale, observations, median_position_residual)
    reports stale. A region the health has seen fitting is refused unless ``force``: the
    refreshed model would only fit measurement noise. ValueError says why."""
    if region:
        if region not in known:
            raise ValueError(f'unknown region "{region}"; known: {", ".join(known)}')
        seen = next((r for r in health if r.name == region), None)
        if seen is not None and seen.observations and not seen.stale and not force:
            raise ValueError(
                f'the model fits region {region}: median residual '
                f'{seen.median_position_residual * 1e3:.3f} mm over its last '
                f'{seen.observations} measurements (stale above {stale_residual * 1e3:.3f} mm);'
                ' a refresh now would only fit measurement noise. Refresh anyway with force '
                '(flexarm refresh --region NAME --force)')
        return [region]
    names = [r.name for r in health if r.stale and r.name in known]
    if not names:
        raise ValueError('the model health reports no stale region; name a region to refresh '
                         'anyway (flexarm refresh --region NAME --force)')
    return names


def refresh_poses(geometry: ArmGeometry, region: Region, worst: np.ndarray, count: int,
                  seed: int = 0) -> np.ndarray:
    """Joints (count, 4): up to ceil(count / 2) of ``worst`` (k, 4), then Sobol poses of
    ``region`` (pass it grown by the coverage margin)."""
    if count < 1:
        raise ValueError('a refresh needs at least 1 sample')
    chosen = np.asarray(worst, dtype=float).reshape(-1, 4)[:(count + 1) // 2]
    rest = count - len(chosen)
    if rest == 0:
        return chosen
    return np.concatenate([chosen, sample_poses(geometry, region, rest, 'sobol', seed)[1]])


def refreshed(predictor: Predictor, geometry: ArmGeometry, joints: np.ndarray,
              deflections: np.ndarray, payload: np.ndarray, version: str) -> Predictor:
    """``predictor`` corrected to the measured ``deflections`` (M, 3) at ``joints`` (M, 4)
    carrying ``payload`` (M,) [kg], as ``version``."""
    joints = np.asarray(joints, dtype=float)
    predicted = predictor.predict(   # the correction must not learn a sag the model carries
        joints, np.asarray(payload, dtype=float) if predictor.carries_payload else None)
    lengths = (geometry.link3, geometry.link4, geometry.offset)
    correction = fit_correction(lengths, joints, deflections, predicted)
    if len(joints) >= 2:
        residuals, std = left_out(lengths, joints, deflections, predicted)
        (position, angle), (spread, turn) = split(residuals), split(std)
        correction = dataclasses.replace(correction, scales=(
            float(np.sqrt(np.sum(position ** 2) / np.sum(spread ** 2))),
            float(np.sqrt(np.sum(angle ** 2) / np.sum(turn ** 2)))))
    return predictor.corrected(correction, version)
