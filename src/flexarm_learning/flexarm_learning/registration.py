"""Rigid registration of measured points to modelled ones: the instrument's frame is not the
arm's base frame, so every calibration tool identifies the instrument-to-base transform first
(here jointly with the model: :mod:`.elastostatic`). Kabsch's solution (scipy's
``Rotation.align_vectors``) starts it."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def kabsch(model: np.ndarray, measured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t with ``measured ≈ model @ R.T + t`` (least squares)."""
    a, b = model.mean(axis=0), measured.mean(axis=0)
    rotation = Rotation.align_vectors(measured - b, model - a)[0].as_matrix()
    return rotation, b - rotation @ a
