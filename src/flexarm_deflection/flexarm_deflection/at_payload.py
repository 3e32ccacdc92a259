"""A deflection model seen at the payload the arm carries now (pure).

Planning (:mod:`flexarm_control.execution.planning`) and the model health call ``predict``,
``data_distance`` and ``position_std`` with joints only. :class:`AtPayload` passes the current
payload [kg] to a model that predicts at the payload it is given
(:attr:`~flexarm_deflection.predictors.Predictor.carries_payload`: it takes the payload as
an input, its ``payload_input`` setting, or carries it physically, the grey-box) and nothing to
one that does not, which predicts at the payloads it was trained at (planning refuses it at
another, :func:`~flexarm_control.execution.planning.payload_beyond`). For a model with the input
the payload counts in the distance from the learned data, so a payload far outside the trained
ones is refused like any other extrapolation; one that carries it physically is not limited by it.
"""
from __future__ import annotations

import numpy as np

from flexarm_deflection.predictors import Predictor


class AtPayload:
    def __init__(self, predictor: Predictor, payload: float) -> None:
        self.predictor = predictor
        self.payload = float(payload)
        self.carried = predictor.carries_payload   # whether the model predicts at ``payload``
        self._given = self.payload if self.carried else None

    def predict(self, joints: np.ndarray) -> np.ndarray:
        return self.predictor.predict(joints, self._given)

    def data_distance(self, joints: np.ndarray) -> np.ndarray | float:
        return self.predictor.data_distance(joints, self._given)

    def position_std(self, joints: np.ndarray) -> np.ndarray | float:
        return self.predictor.position_std(joints, self._given)

    def prior_std(self, joints: np.ndarray) -> np.ndarray:
        return self.predictor.prior_std(joints, self._given)

    def error_bound(self, joints: np.ndarray) -> np.ndarray:
        return self.predictor.error_bound(joints, self._given)
