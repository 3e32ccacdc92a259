"""``auto``: the kind that fits the dataset best, chosen by grouped cross-validation.

No single kind wins everywhere (`flexarm study`): the grey-box where the arm follows its structure
(on the simulated arm, every region and size), the GP where something the structure lacks
dominates (paper region with friction, 40 samples: on the worst seed), kinematic calibration
alone where the arm is stiff and only miscalibrated. So ``auto`` cross-validates every setting
candidate of each of its ``kinds`` (:func:`flexarm_control.learning.training.fit_robust`: held-out
poses grouped, the trimmed RMS score) and keeps the single best one, fitted on all samples. It
picks rather than averages: the mean of the grey-box and GP predictions missed the held-out truth
by more than the choice in all six cases on the mean over seeds, five on the worst seed (regions
A, B, paper × 20, 40 samples, 3 seeds, with friction, thermal strain and noise), and one model
keeps the GP's position std meaningful. The MLP is not among the default kinds: it adds ~60 %
to the training time (40 samples of region A, one thread: 1.4 s → 2.3 s) and never scored best
in regions A, B or paper; add it to ``kinds`` to let it compete.

The model is an :class:`AutoPredictor` that predicts with the chosen one; the metadata's
``auto`` entry says which (``chosen``, its ``settings``), the score of every kind (``scores``:
trimmed RMS of held-out residuals over the output std, lower is better) and holds the chosen
model's metadata (``model``); the model file holds the chosen model's arrays as its own.
Through :func:`~flexarm_control.learning.training.fit_robust` (the learner) the choice is made
once, together with the outlier screening; :meth:`AutoPredictor.fit` on its own makes it without
screening.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from flexarm_control.learning.predictors.base import Predictor, restore

FOLDS = 5     # of the cross-validation of AutoPredictor.fit (the learner's validation_folds)


class AutoPredictor(Predictor):
    """The best of ``kinds`` for the data, by grouped cross-validation."""

    kind: ClassVar[str] = 'auto'
    defaults: ClassVar[dict[str, Any]] = {
        'kinds': ['kinematic', 'greybox', 'gp'], 'seed': 0, 'payload_input': False}
    physical: ClassVar[bool] = True

    def _check_settings(self) -> None:
        from flexarm_control.learning.predictors import KINDS

        kinds = self.settings['kinds']
        if not kinds or not set(kinds) <= set(KINDS) - {self.kind}:
            raise ValueError(f"auto 'kinds' must be some of "
                             f"{[k for k in KINDS if k != self.kind]}, got {kinds}")

    def kind_settings(self, kind: str) -> dict[str, Any]:
        """The settings ``auto`` gives a kind of its choice (the others are chosen by
        cross-validation or take their defaults)."""
        from flexarm_control.learning.predictors import make_predictor

        given = {'payload_input': self.settings['payload_input']}
        if 'seed' in make_predictor(kind).defaults:
            given['seed'] = self.settings['seed']
        return given

    def adopt(self, chosen: Predictor, scores: Mapping[str, float]) -> AutoPredictor:
        """This predictor made the fitted ``chosen`` one, which scored best of ``scores``."""
        self._chosen = chosen
        self._normalisation, self._support = chosen._normalisation, chosen._support
        self.metadata.update({name: chosen.metadata[name] for name in (
            'created', 'version', 'samples', 'normalisation', 'support_spacing')})
        self.metadata['auto'] = {'chosen': chosen.kind, 'settings': chosen.settings,
                                 'scores': dict(scores), 'model': chosen.metadata}
        return self

    @property
    def chosen(self) -> Predictor:
        """The fitted model it predicts with."""
        self._require_fitted()
        return self._chosen

    @property
    def payload_physical(self) -> bool:
        """The chosen model's."""
        return self.chosen.payload_physical

    def _fit_physical(self, joints: np.ndarray, payload: np.ndarray | None,
                      deflections: np.ndarray) -> None:
        from flexarm_control.learning.training import NO_SCREENING, fit_robust

        model, _ = fit_robust(self.kind, self.settings, joints, deflections, payload, FOLDS,
                              self.settings['seed'], screening=NO_SCREENING)
        self.adopt(model.chosen, model.metadata['auto']['scores'])

    def _predict_physical(self, joints: np.ndarray, payload: np.ndarray | None) -> np.ndarray:
        return self._chosen.predict(joints, payload)

    def position_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                     ) -> np.ndarray | float:
        """The chosen model's."""
        return self.chosen.position_std(joints, payload)

    def deflection_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                       ) -> np.ndarray:
        """The chosen model's."""
        return self.chosen.deflection_std(joints, payload)

    def prior_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                  ) -> np.ndarray:
        """The chosen model's."""
        return self.chosen.prior_std(joints, payload)

    def _state(self) -> dict[str, np.ndarray]:
        return self._chosen._state()

    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        from flexarm_control.learning.predictors import _class_of

        meta = self.metadata['auto']
        self._chosen = restore(_class_of(meta['chosen']), meta['model'], state)
