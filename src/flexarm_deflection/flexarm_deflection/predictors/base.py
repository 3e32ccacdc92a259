"""Deflection predictor interface, normalisation and the atomic single-file model format.

A :class:`Predictor` maps joint positions θ = (θ1 rad, θ2 m, θ3 rad, θ4 rad), plus the payload
[kg] as a fifth input when its ``payload_input`` setting is true, to the tip deflection (dx m,
dy m, dφ rad) = measured − rigid pose. Its inputs are the link angles gravity acts on
(:func:`model_inputs`), z-scored with the training set's statistics (:class:`Normalisation`):
the learned kinds (:mod:`.mlp`, :mod:`.rbf`, :mod:`.gp`) see only that space, the ``physical``
ones (:mod:`.kinematic`, :mod:`.greybox`, ``auto`` of
:mod:`~flexarm_deflection.selection`) take the joints and the payload in SI units.
:meth:`Predictor.data_distance` says how far a query lies from the training data.
:meth:`Predictor.save` writes a model file atomically (one ``.npz``, no pickle, format
``FORMAT_VERSION``) and :func:`read_model` reads it. scipy is imported only in the functions
that use it.

Explained in docs/learning.md#predictors-and-model-files.
"""
from __future__ import annotations

import copy
import json
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from flexarm_core.atomic_file import atomic_write
from flexarm_deflection.drift_correction import Correction
from flexarm_deflection.error_bound import BoundCalibration, correction_bound

if TYPE_CHECKING:
    from threadpoolctl import ThreadpoolController

FORMAT_VERSION = 2        # 2: link-angle inputs and the learned-data support
JOINTS = 4
OUTPUTS = 3
_CONSTANT_STD = 1e-12     # an input with a smaller spread in the training set is dropped
CONSTANT_INPUT_SCALE = 1e-3  # [rad, m, kg] unit of data_distance along a dropped input
NEAREST_BLOCK = 1_000_000  # point pairs nearest_distance holds at once (d floats each)
# [kg] a payload this close to a trained one counts as that one: the tip sags at most 3.6 mm
# per kg over the learner's regions (simulated arm), so 10 g is <= 0.04 mm, the joints'
# repeatability at the tip; payloads are declared to a gram or two.
PAYLOAD_TOLERANCE = 0.01


def model_inputs(joints: np.ndarray) -> np.ndarray:
    """The link angles of joints (..., 4): θ1, θ2, θ1 + θ3, θ1 + θ3 + θ4."""
    q = np.asarray(joints, dtype=float)
    return np.stack([q[..., 0], q[..., 1], q[..., 0] + q[..., 2],
                     q[..., 0] + q[..., 2] + q[..., 3]], axis=-1)


@dataclass(frozen=True)
class Normalisation:
    """Z-score of inputs (constant ones dropped) and outputs, from a training set."""

    input_mean: np.ndarray
    input_std: np.ndarray
    active_inputs: np.ndarray   # bool mask of the inputs the model uses
    output_mean: np.ndarray
    output_std: np.ndarray

    @classmethod
    def of(cls, inputs: np.ndarray, outputs: np.ndarray) -> Normalisation:
        input_std = inputs.std(axis=0)
        active = input_std > _CONSTANT_STD
        output_std = outputs.std(axis=0)
        return cls(inputs.mean(axis=0), np.where(active, input_std, 1.0), active,
                   outputs.mean(axis=0), np.where(output_std > 0, output_std, 1.0))

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Normalisation:
        return cls(*(np.asarray(d[name], dtype=bool if name == 'active_inputs' else float)
                     for name in ('input_mean', 'input_std', 'active_inputs', 'output_mean',
                                  'output_std')))

    def as_dict(self) -> dict[str, list]:
        return {name: getattr(self, name).tolist() for name in
                ('input_mean', 'input_std', 'active_inputs', 'output_mean', 'output_std')}

    def inputs(self, x: np.ndarray) -> np.ndarray:
        return ((x - self.input_mean) / self.input_std)[:, self.active_inputs]

    def outputs(self, y: np.ndarray) -> np.ndarray:
        return (y - self.output_mean) / self.output_std

    def outputs_back(self, z: np.ndarray) -> np.ndarray:
        return z * self.output_std + self.output_mean


def _coerce(name: str, value: Any, default: Any) -> Any:
    """``value`` converted to the type of ``default`` (int → float allowed), else ValueError."""
    if isinstance(default, list):
        if not isinstance(value, (list, tuple)):
            raise ValueError(f'setting {name!r} must be a list, got {value!r}')
        return [_coerce(name, item, default[0]) for item in value]
    is_bool = isinstance(value, (bool, np.bool_))
    if isinstance(default, bool):
        ok = is_bool
    elif isinstance(default, int):
        ok = isinstance(value, (int, np.integer)) and not is_bool
    elif isinstance(default, float):
        ok = isinstance(value, (int, float, np.integer, np.floating)) and not is_bool
    else:
        ok = isinstance(value, type(default))
    if not ok:
        raise ValueError(f'setting {name!r} must be of type {type(default).__name__}, '
                         f'got {value!r}')
    return type(default)(value)


class Predictor(ABC):
    """Deflection predictor Δ(θ[, payload]) → (dx, dy, dφ); docs/learning.md explains the kinds."""

    kind: ClassVar[str]
    defaults: ClassVar[dict[str, Any]]   # every setting with its default value
    # Settings that training chooses by cross-validation, with the values to try, unless the
    # user sets them.
    cv_choices: ClassVar[dict[str, list[Any]]] = {}
    # Settings the cross-validation fits take instead of the defaults (cheaper; the final fit
    # keeps the defaults), unless the user sets them.
    cv_overrides: ClassVar[dict[str, Any]] = {}
    # True: the kind is fitted and queried on the joints (N, 4) and the payload (N,) [kg] (None
    # unless given) in SI units (:meth:`_fit_physical`, :meth:`_predict_physical`), not on the
    # normalised space.
    physical: ClassVar[bool] = False

    def __init__(self, settings: Mapping[str, Any] | None = None) -> None:
        given = dict(settings or {})
        unknown = sorted(set(given) - set(self.defaults))
        if unknown:
            raise ValueError(f'unknown {self.kind} settings {unknown}; '
                             f'known: {sorted(self.defaults)}')
        self.settings: dict[str, Any] = {
            name: _coerce(name, given.get(name, default), default)
            for name, default in self.defaults.items()}
        self._check_settings()
        self.metadata: dict[str, Any] = {
            'kind': self.kind, 'settings': self.settings, 'format': FORMAT_VERSION,
            'version': '', 'created': '', 'samples': 0, 'normalisation': None,
            'dataset_hash': '', 'metrics': None, 'support_spacing': None}
        self._normalisation: Normalisation | None = None
        self._support: np.ndarray | None = None
        self.corrections: list[Correction] = []   # refreshes (drift_correction), in order

    @abstractmethod
    def _check_settings(self) -> None:
        """Raise ValueError for settings out of range."""

    def _fit_normalised(self, x: np.ndarray, y: np.ndarray) -> None:
        """Fit on normalised inputs (N, d) and outputs (N, 3) (kinds not ``physical``)."""
        raise NotImplementedError

    def _predict_normalised(self, x: np.ndarray) -> np.ndarray:
        """Normalised outputs (M, 3) for normalised inputs (M, d) (kinds not ``physical``)."""
        raise NotImplementedError

    def _fit_physical(self, joints: np.ndarray, payload: np.ndarray | None,
                      deflections: np.ndarray) -> None:
        """Fit on joints (N, 4), payload (N,) or None (not given) and deflections (N, 3)
        (``physical``)."""
        raise NotImplementedError

    def _predict_physical(self, joints: np.ndarray, payload: np.ndarray | None) -> np.ndarray:
        """Deflections (M, 3) at joints (M, 4) and payload (M,) or None (not given)
        (``physical``)."""
        raise NotImplementedError

    @abstractmethod
    def _state(self) -> dict[str, np.ndarray]:
        """Arrays that, with the metadata, restore the fitted model."""

    @abstractmethod
    def _restore(self, state: Mapping[str, np.ndarray]) -> None:
        """Inverse of :meth:`_state`."""

    @property
    def fitted(self) -> bool:
        return self._normalisation is not None

    @property
    def payload_physical(self) -> bool:
        """Whether the model carries the payload physically (how it loads the arm), so that it
        predicts at a payload it has no samples of without taking it as an input."""
        return False

    @property
    def carries_payload(self) -> bool:
        """Whether the model predicts at the payload it is given: as an input
        (``payload_input``) or physically (:attr:`payload_physical`)."""
        return self.settings['payload_input'] or self.payload_physical

    def fit(self, joints: np.ndarray, deflections: np.ndarray,
            payload: np.ndarray | None = None) -> Predictor:
        """Fit on joints (N, 4), deflections (N, 3) [m, m, rad] and payload (N,) [kg]."""
        q, p, _ = self._query(joints, payload)
        x = self._model_inputs(q, p)
        y = np.asarray(deflections, dtype=float)
        if y.shape != (len(x), OUTPUTS):
            raise ValueError(f'deflections must have shape ({len(x)}, {OUTPUTS}), '
                             f'got {y.shape}')
        if not np.all(np.isfinite(y)):
            raise ValueError('deflections contain NaN or infinite values')
        if len(x) < 2:
            raise ValueError(f'at least 2 samples are needed to fit, got {len(x)}')
        normalisation = Normalisation.of(x, y)
        support = normalisation.inputs(x)
        with _blas().limit(limits=1, user_api='blas'):
            if self.physical:
                self._fit_physical(q, p, y)
            else:
                self._fit_normalised(support, normalisation.outputs(y))
        self._normalisation, self._support = normalisation, support
        now = datetime.now(UTC)
        self.metadata.update(created=now.isoformat(), version=now.strftime('%Y%m%dT%H%M%S.%fZ'),
                             samples=len(x), normalisation=normalisation.as_dict(),
                             support_spacing=_spacing(support))
        return self

    def data_distance(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                      ) -> np.ndarray | float:
        """Distance of the query (joints (4,) or (M, 4)) from the training data, in typical
        sample spacings (docs/learning.md): a float, or (M,)."""
        x, single = self._inputs(joints, payload)
        n = self._require_fitted()
        z = (x - n.input_mean) / n.input_std
        dropped = ((x - n.input_mean)[:, ~n.active_inputs] / CONSTANT_INPUT_SCALE) ** 2
        nearest = nearest_distance(self._support, z[:, n.active_inputs])
        distance = np.sqrt(nearest ** 2 + dropped.sum(axis=1)) / self.metadata['support_spacing']
        return float(distance[0]) if single else distance

    def predict(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                ) -> np.ndarray:
        """Deflection (3,) for joints (4,), or (M, 3) for joints (M, 4)."""
        q, p, single = self._query(joints, payload)
        y = self._uncorrected(q, p)
        for correction in self.corrections:
            y = correction.apply(q, y)
        return y[0] if single else y

    def _uncorrected(self, q: np.ndarray, p: np.ndarray | None) -> np.ndarray:
        """(M, 3): the fitted model's deflection at joints (M, 4), before any refresh."""
        normalisation = self._require_fitted()
        return (self._predict_physical(q, p) if self.physical else normalisation.outputs_back(
            self._predict_normalised(normalisation.inputs(self._model_inputs(q, p)))))

    def corrected(self, correction: Correction, version: str) -> Predictor:
        """This model with ``correction`` added to its prediction (a refresh), as ``version``;
        this one is left unchanged."""
        self._require_fitted()
        new = copy.copy(self)
        new.corrections = [*self.corrections, correction]
        new.metadata = {**self.metadata, 'version': version,
                        'corrections': [c.as_dict() for c in new.corrections]}
        return new

    def position_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                     ) -> np.ndarray | float:
        """Standard deviation [m] of the predicted tip position at joints (4,) or (M, 4) for
        kinds with a posterior (the GP); 0 for the others, which have none."""
        x, single = self._inputs(joints, payload)
        return 0.0 if single else np.zeros(len(x))

    def deflection_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                       ) -> np.ndarray:
        """The model's own standard deviation of its predicted deflection [m, m, rad] at
        joints (4,) or (M, 4), shaped like :meth:`predict`: what the samples it was fitted on
        leave open (the GP: its posterior; the physical kinds: their fitted parameters'
        covariance; the MLP: its ensemble's spread); zeros for a kind without one. Raw: the
        learner scales it on held-out samples into a 95 % bound (:mod:`..error_bound`)."""
        x, single = self._inputs(joints, payload)
        return np.zeros(OUTPUTS) if single else np.zeros((len(x), OUTPUTS))

    def prior_std(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                  ) -> np.ndarray:
        """Standard deviation [m, m, rad] of what the samples cannot tell and a prior bounds,
        shaped like :meth:`predict` (the grey-box: how a payload loads an arm whose masses are
        known only nominally, when every sample had one payload); zeros for the others."""
        return np.zeros_like(self.deflection_std(joints, payload))

    def error_bound(self, joints: np.ndarray, payload: np.ndarray | float | None = None,
                    ) -> np.ndarray:
        """95 % bound [m, rad] of the predicted tip position's and angle's error at joints
        (4,) → (2,) or (M, 4) → (M, 2): the raw std scaled by the learner's held-out
        calibration (metadata ``error_bound``, :mod:`..error_bound`) with the prior's term;
        NaN for a model fitted without one (not by the learner's training)."""
        std = self.deflection_std(joints, payload)
        calibration = self.metadata.get('error_bound')
        if calibration is None:
            return np.full(std.shape[:-1] + (2,), np.nan)
        bound = BoundCalibration.from_dict(calibration).bound(std, self.prior_std(joints, payload))
        if not self.corrections:
            return bound
        return np.hypot(bound, correction_bound(self._correction_std(joints, payload)))

    def _correction_std(self, joints: np.ndarray, payload: np.ndarray | float | None,
                        ) -> np.ndarray:
        """(…, 3) [m, m, rad]: the refreshes' own uncertainty, independent, in quadrature."""
        q, p, single = self._query(joints, payload)
        y = self._uncorrected(q, p)
        variance = np.zeros_like(y)
        for correction in self.corrections:
            variance += correction.std(q, y) ** 2
            y = correction.apply(q, y)
        std = np.sqrt(variance)
        return std[0] if single else std

    def save(self, path: str | Path) -> None:
        """Write the fitted model to ``path`` atomically (format: docs/learning.md)."""
        self._require_fitted()
        arrays = {f'{self.kind}.{name}': value for name, value in self._state().items()}
        metadata = np.array(json.dumps(self.metadata))
        atomic_write(path, lambda file: np.savez(file, metadata=metadata,
                                                 support=self._support, **arrays))

    def _require_fitted(self) -> Normalisation:
        if self._normalisation is None:
            raise RuntimeError(f'the {self.kind} predictor is not fitted')
        return self._normalisation

    def _inputs(self, joints: np.ndarray, payload: np.ndarray | float | None,
                ) -> tuple[np.ndarray, bool]:
        """Model inputs (N, 4 or 5) and whether a single (4,) query was given."""
        q, p, single = self._query(joints, payload)
        return self._model_inputs(q, p), single

    def _model_inputs(self, joints: np.ndarray, payload: np.ndarray | None) -> np.ndarray:
        x = model_inputs(joints)
        return np.column_stack([x, payload]) if self.settings['payload_input'] else x

    def _query(self, joints: np.ndarray, payload: np.ndarray | float | None,
               ) -> tuple[np.ndarray, np.ndarray | None, bool]:
        """Joints (N, 4), payload (N,) (None unless ``payload_input``, or given to a
        ``physical`` kind) and whether a single (4,) query was given; ValueError for a wrong
        shape or a value not finite."""
        q = np.asarray(joints, dtype=float)
        single = q.ndim == 1
        if single:
            q = q[np.newaxis]
        if q.ndim != 2 or q.shape[1] != JOINTS:
            raise ValueError(f'joints must have shape ({JOINTS},) or (N, {JOINTS}), '
                             f'got {np.shape(joints)}')
        p = None
        if self.settings['payload_input'] and payload is None:
            raise ValueError(f'this {self.kind} predictor takes the payload as an input')
        if payload is not None and (self.settings['payload_input'] or self.physical):
            p = np.asarray(payload, dtype=float)
            if p.ndim == 0:
                p = np.full(len(q), float(p))
            if p.shape != (len(q),):
                raise ValueError(f'payload must be a scalar or have shape ({len(q)},), '
                                 f'got {np.shape(payload)}')
        if not (np.isfinite(q).all() and (p is None or np.isfinite(p).all())):
            raise ValueError('joints or payload contain NaN or infinite values')
        return q, p, single


def read_model(path: str | Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Metadata and the arrays of a model file: the kind's (names without the kind prefix)
    and ``support``.

    OSError if the file cannot be read; ValueError for a file that is not a model file of a
    supported format (empty, truncated, damaged or foreign).
    """
    try:
        with np.load(path, allow_pickle=False) as archive:
            metadata = json.loads(str(archive['metadata']))
            prefix = f"{metadata['kind']}."
            state = {name[len(prefix):]: archive[name] for name in archive.files
                     if name.startswith(prefix)}
            if 'support' in archive.files:
                state['support'] = archive['support']
    except OSError:
        raise
    except Exception as exc:   # numpy, zipfile and json raise many types for a damaged file
        raise ValueError(f'{path} is not a model file (empty, truncated or damaged): '
                         f'{type(exc).__name__}: {exc}') from exc
    model_format = metadata.get('format', 0)
    if (not isinstance(metadata['kind'], str) or isinstance(model_format, bool)
            or not isinstance(model_format, int)):
        raise ValueError(f'{path} is not a model file (bad metadata kind or format)')
    if model_format != FORMAT_VERSION:
        raise ValueError(f'{path}: model format {model_format}, this version reads only '
                         f'format {FORMAT_VERSION}' + (
                             ' (older models took other inputs and lack the learned-data '
                             'support): train a new one' if model_format < FORMAT_VERSION
                             else ''))
    return metadata, state


def restore(cls: type[Predictor], metadata: dict[str, Any],
            state: Mapping[str, np.ndarray]) -> Predictor:
    """A fitted predictor of class ``cls`` from a model file's content.

    ValueError if the content is incomplete or inconsistent: the restored model must give a
    finite deflection at the mean of its training inputs.
    """
    try:
        predictor = cls(metadata['settings'])
        predictor.metadata = metadata
        predictor._normalisation = Normalisation.from_dict(metadata['normalisation'])
        predictor._support = np.asarray(state['support'], dtype=float)
        if not float(metadata['support_spacing']) > 0:
            raise ValueError(f"support_spacing {metadata['support_spacing']}")
        predictor._restore(state)
        predictor.corrections = [Correction.from_dict(c)
                                 for c in metadata.get('corrections', [])]
        mean = predictor._normalisation.input_mean    # link angles: back to joints
        joints = np.array([mean[0], mean[1], mean[2] - mean[0], mean[3] - mean[2]])
        probe = predictor.predict(joints,
                                  mean[JOINTS] if predictor.settings['payload_input'] else None)
    except Exception as exc:   # missing entries, wrong types or shapes: many types
        raise ValueError(f'inconsistent {cls.kind} model: {type(exc).__name__}: {exc}') from exc
    if np.shape(probe) != (OUTPUTS,) or not np.all(np.isfinite(probe)):
        raise ValueError(f'inconsistent {cls.kind} model: it predicts {probe}')
    return predictor


@cache
def _blas() -> ThreadpoolController:
    """The BLAS libraries, limited to one thread while fitting: the matrices of tens of samples
    are too small to share out, a second thread only waits (GP fits took 3-5× the CPU time
    with two on a busy 2-core machine). Created at the first fit (importing threadpoolctl
    costs ~30 ms), when numpy's and scipy's BLAS are loaded."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


def nearest_distance(support: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance (M,) from each of ``points`` (M, d) to its nearest point of ``support`` (N, d),
    by brute force in blocks of at most ``NEAREST_BLOCK`` pairs. A plan asks it for one point
    against at most some thousands of samples (microseconds); a KD tree (scipy.spatial, as
    training's :func:`_spacing` uses) would cost the compensator 0.35 s of CPU to import at
    its first goal."""
    rows = max(1, NEAREST_BLOCK // max(1, len(support)))
    blocks = [np.sqrt(((points[i:i + rows, None, :] - support[None]) ** 2).sum(axis=2).min(axis=1))
              for i in range(0, len(points), rows)]
    return np.concatenate(blocks) if blocks else np.zeros(0)


def _spacing(support: np.ndarray) -> float:
    """Median distance from a point of ``support`` to its nearest other point (1 if all
    points coincide)."""
    from scipy.spatial import cKDTree

    nearest = cKDTree(support).query(support, k=2)[0][:, 1]
    spacing = float(np.median(nearest))
    return spacing if spacing > 0 else 1.0
