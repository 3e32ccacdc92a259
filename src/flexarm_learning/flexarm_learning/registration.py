"""Rigid registration of measured points to modelled ones: the instrument's frame is not the
arm's base frame, so every calibration tool identifies the instrument-to-base transform first
(here jointly with the model: :mod:`.elastostatic`). Kabsch's solution starts it.

Kabsch by its SVD, not scipy's ``Rotation.align_vectors``: on the JAERI arm's samples the two
rotations differ by 2e-16, yet the fit from scipy's ended at 0.024 mm instead of 0.006 mm in
benchmarks/core_on_jaeri.py's region A. Planar points leave some of the registration
undetermined, and there round-off decides where the fit ends; the figures quoted were
measured from this start.
"""
from __future__ import annotations

import numpy as np


def kabsch(model: np.ndarray, measured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t with ``measured ≈ model @ R.T + t`` (least squares)."""
    a, b = model.mean(axis=0), measured.mean(axis=0)
    u, _, vt = np.linalg.svd((model - a).T @ (measured - b))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rotation = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return rotation, b - rotation @ a
