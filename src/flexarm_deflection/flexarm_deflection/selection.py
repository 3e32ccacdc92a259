"""Model selection: the kind and settings that fit the data best, its outliers screened, and a
model the compensator can solve with (pure core of the learner's training).

:func:`fit_robust`:

1. **Cross-validation** (k-fold, :func:`~flexarm_deflection.cross_validation.
   cross_validate`) of every combination of the kind's ``cv_choices`` the caller did not fix
   (MLP weight decay, GP kernel, RBF smoothing), with the kind's cheaper ``cv_overrides`` (GP:
   1 restart); the one with the lowest trimmed RMS held-out error (the worst 10 % of samples
   left out, so one bad sample cannot choose) wins. Kind ``auto`` chooses among the candidates
   of every kind of its ``kinds`` at once; the model is an :class:`AutoPredictor` of the
   chosen one.
2. **Outlier screening** (:class:`~flexarm_deflection.cross_validation.Screening`): the
   worst outlier is excluded, then the chosen settings are validated again without it, at most
   ``max_outlier_fraction`` of the samples (the choice of step 1 stands: its trimmed score
   already ignores a bad sample); excluded samples that the model of the kept ones does not
   contradict are taken back. The floor (1 mm, 2 mrad) is what a real sharp feature cannot
   explain: held-out residuals of good samples reach ~0.5 mm at the edges of the sampled region
   and across the backlash step of joint4. The metrics list the excluded samples by their index
   in the data.
3. **Solvability**: the model fitted on the kept samples must change its deflection slower
   than the commanded pose, :func:`~flexarm_deflection.deflection_slope.deflection_slope`
   ≤ ``max_slope`` at every training pose (the true arm: ≤ 0.1); otherwise the next-best choice
   of step 1 is fitted, and if none passes, the fit fails with the reason.

``auto``, the learner's default kind, is model selection made a model: an :class:`AutoPredictor`
predicts with the kind it chose.

No single kind wins everywhere (`flexarm study`): the grey-box where the arm follows its structure
(on the simulated arm, every region and size), the GP where something the structure lacks
dominates (paper region with friction, 40 samples: on the worst seed), kinematic calibration
alone where the arm is stiff and only miscalibrated. So ``auto`` cross-validates every setting
candidate of each of its ``kinds`` (:func:`fit_robust`: held-out
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
Through :func:`fit_robust` (the learner) the choice is made
once, together with the outlier screening; :meth:`AutoPredictor.fit` on its own makes it without
screening.
"""
from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from flexarm_core.kinematics import ArmGeometry
from flexarm_deflection.cross_validation import (
    DEFAULT_SCREENING,
    NO_SCREENING,
    ROBUST_SCALE,
    Metrics,
    Screening,
    candidates,
    check_data,
    cross_validate,
    outlier_scores,
    pose_groups,
    subset,
    trimmed_rms,
)
from flexarm_deflection.deflection_slope import deflection_slope
from flexarm_deflection.error_bound import calibrate
from flexarm_deflection.predictors import (
    KINDS,
    Predictor,
    make_predictor,
    predictor_class,
    restore,
)

FOLDS = 5     # of the cross-validation of AutoPredictor.fit (the learner's validation_folds)


class AutoPredictor(Predictor):
    """The best of ``kinds`` for the data, by grouped cross-validation."""

    kind: ClassVar[str] = 'auto'
    defaults: ClassVar[dict[str, Any]] = {
        'kinds': ['kinematic', 'greybox', 'gp'], 'seed': 0, 'payload_input': False}
    physical: ClassVar[bool] = True

    def _check_settings(self) -> None:
        kinds = self.settings['kinds']
        if not kinds or not set(kinds) <= set(KINDS):
            raise ValueError(f"auto 'kinds' must be some of {list(KINDS)}, got {kinds}")

    def kind_settings(self, kind: str) -> dict[str, Any]:
        """The settings ``auto`` gives a kind of its choice (the others are chosen by
        cross-validation or take their defaults)."""
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
        meta = self.metadata['auto']
        self._chosen = restore(predictor_class(meta['chosen']), meta['model'], state)


def options(kind: str, settings: Mapping[str, Any] | None
             ) -> list[tuple[str, dict[str, Any], dict[str, Any]]]:
    """(kind, settings, the settings given rather than chosen) to choose among: the
    :func:`candidates` of ``kind``, or for ``auto`` those of each of its kinds."""
    if kind != 'auto':
        given = dict(settings or {})
        return [(kind, option, given) for option in candidates(kind, given)]
    auto = AutoPredictor(settings)
    return [(k, option, auto.kind_settings(k)) for k in auto.settings['kinds']
            for option in candidates(k, auto.kind_settings(k))]


def _slope(geometry: ArmGeometry, predictor: Predictor, joints: np.ndarray,
           payload: np.ndarray | None) -> float:
    """The largest :func:`deflection_slope` of ``predictor`` at ``joints`` (N, 4), each at
    its own payload."""
    groups = [(None, joints)] if payload is None else [
        (p, joints[payload == p]) for p in np.unique(payload)]
    return max(float(deflection_slope(
        geometry, lambda q, p=p: predictor.predict(q, p), q).max()) for p, q in groups)


def fit_robust(kind: str, settings: Mapping[str, Any] | None, joints: np.ndarray,
               deflections: np.ndarray, payload: np.ndarray | None = None, folds: int = 5,
               seed: int = 0, geometry: ArmGeometry | None = None,
               screening: Screening = DEFAULT_SCREENING) -> tuple[Predictor, Metrics]:
    """Steps 1-3 of the module docstring on arrays; the fitted predictor and its metrics.

    Screening excludes the worst outlier and validates again until none is left; then the
    model fitted on the kept samples predicts the excluded ones, and those it does not
    contradict (a bad sample's neighbours can look bad while it is in the data) are taken
    back and screened once more. Without ``geometry`` the solvability check is skipped.
    """
    choices = options(kind, settings)
    for option_kind, option, _ in choices:
        make_predictor(option_kind, option)   # unknown kind or bad settings: fail before any fit
    joints, deflections, payload = check_data(joints, deflections, payload, folds)
    output_std = deflections.std(axis=0)
    output_std = np.where(output_std > 0, output_std, 1.0)
    fits = _Fits(kind, choices, joints, deflections, payload, folds, seed)
    first = [fits.validate(i) for i in range(len(choices))]
    cv_scores = [trimmed_rms(residuals, output_std) for residuals, _ in first]
    ranked = sorted(range(len(choices)), key=lambda i: cv_scores[i])
    best, (residuals, std) = ranked[0], first[ranked[0]]
    residuals, std = fits.screen(best, residuals, std, screening,
                                 int(screening.max_outlier_fraction * len(joints)))
    slopes = []
    for i in ranked:            # the best choice, unless the compensator could not solve with it
        if i != best:
            residuals, std = fits.validate(i)
        predictor = fits.fit(i)
        slope = (0.0 if geometry is None else
                 _slope(geometry, predictor, joints[fits.kept], subset(payload, fits.kept)))
        if slope <= screening.max_slope:
            calibration = calibrate(residuals, std, pose_groups(joints[fits.kept]))
            metrics = Metrics.from_errors(
                f'{folds}-fold cross-validation', len(fits.kept), np.abs(residuals),
                excluded_samples=tuple(int(e) for e in sorted(fits.excluded)),
                selected_settings=json.dumps(fits.label(i)), max_slope=slope,
                bound_coverage=calibration.coverage,
                angle_bound_coverage=calibration.angle_coverage)
            if kind == 'auto':
                by_kind = {k: min(score for (option_kind, _, _), score
                                  in zip(choices, cv_scores) if option_kind == k)
                           for k, _, _ in choices}
                predictor = AutoPredictor(settings).adopt(predictor, by_kind)
            predictor.metadata['error_bound'] = calibration.as_dict()
            return predictor, metrics
        slopes.append(f'{json.dumps({**fits.label(i), **choices[i][1]})}: {slope:.2f}')
    raise ValueError(
        'every model changes its deflection too fast for the compensator to solve '
        f'(slope > {screening.max_slope} at a training pose; {"; ".join(slopes)}): the data '
        'are too sparse or too noisy — collect more samples')


class _Fits:
    """The options of one :func:`fit_robust` on the samples it keeps: each validated, fitted
    and labelled on ``kept``, which screening narrows (``excluded``: the rest)."""

    def __init__(self, kind: str, choices: list[tuple[str, dict[str, Any], dict[str, Any]]],
                 joints: np.ndarray, deflections: np.ndarray, payload: np.ndarray | None,
                 folds: int, seed: int) -> None:
        self.kind, self.choices = kind, choices
        self.joints, self.deflections, self.payload = joints, deflections, payload
        self.folds, self.seed = folds, seed
        self.kept, self.excluded = np.arange(len(joints)), np.array([], dtype=int)

    def validate(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Held-out residuals and raw stds of option ``i`` on the kept samples."""
        option_kind, option, given = self.choices[i]
        cheaper = {name: value for name, value in make_predictor(option_kind).cv_overrides.items()
                   if name not in given}
        return cross_validate(option_kind, {**option, **cheaper}, self.joints[self.kept],
                              self.deflections[self.kept], subset(self.payload, self.kept),
                              self.folds, self.seed)

    def fit(self, i: int) -> Predictor:
        option_kind, option, _ = self.choices[i]
        return make_predictor(option_kind, option).fit(
            self.joints[self.kept], self.deflections[self.kept], subset(self.payload, self.kept))

    def label(self, i: int) -> dict[str, Any]:
        """The settings option ``i`` chose (and its kind, for ``auto``)."""
        option_kind, option, given = self.choices[i]
        chosen = {name: option[name] for name in option if name not in given}
        return chosen if self.kind != 'auto' else {'kind': option_kind, **chosen}

    def screen(self, best: int, residuals: np.ndarray, std: np.ndarray, screening: Screening,
               most: int) -> tuple[np.ndarray, np.ndarray]:
        """Exclude outliers of option ``best`` (at most ``most``), take back what the screened
        model does not contradict, screen once more; its residuals and stds after."""
        for _ in range(2):
            while True:
                scale = ROBUST_SCALE * np.median(np.abs(residuals), axis=0)
                scores = outlier_scores(residuals, scale, screening)
                if not scores.max() > 0 or len(self.excluded) >= most:
                    break
                worst = int(np.argmax(scores))
                self.excluded = np.append(self.excluded, self.kept[worst])
                self.kept = np.delete(self.kept, worst)
                residuals, std = self.validate(best)
            if not len(self.excluded):
                break
            predicted = self.fit(best).predict(self.joints[self.excluded],
                                               subset(self.payload, self.excluded))
            back = outlier_scores(predicted - self.deflections[self.excluded], scale,
                                  screening) == 0
            if not back.any():
                break
            self.kept = np.sort(np.append(self.kept, self.excluded[back]))
            self.excluded = self.excluded[~back]
            residuals, std = self.validate(best)
        return residuals, std
