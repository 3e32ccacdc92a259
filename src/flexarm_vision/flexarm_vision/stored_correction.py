"""A correction the vision node applies, kept in a site calibration file and settable at run
time (pure): the tool correction and the camera correction share this bookkeeping.

The value comes from the file when there is one (a damaged file is a ``problem``: the node runs
uncorrected and says so), else the neutral value; ``flexarm calibrate`` writes the file and then
sets the node's parameter, so a value set at run time is recognised as the file's when the file
holds it, and as the parameter's alone (lost at a restart) otherwise.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any, Generic, Protocol, TypeVar

import numpy as np


class Correction(Protocol):
    def as_list(self) -> list[float]: ...


C = TypeVar('C', bound=Correction)


class StoredCorrection(Generic[C]):
    """The correction in use and where it came from: ``source`` is 'none' (neutral: no file),
    'parameter' (set at run time, not what the file holds) or the file's path."""

    def __init__(self, path: str, read: Callable[[str], dict[str, Any] | None],
                 neutral: C) -> None:
        self.path = path
        self._read = read
        self.problem = ''                      # why the file cannot be used, '' if it can
        self.record = self._load()
        self.source = 'none' if self.record is None else path
        self.value: C = neutral if self.record is None else self.record['correction']

    def set(self, value: C) -> None:
        """Use ``value`` (a parameter set at run time): the file's if it holds it."""
        self.value = value
        record = self._load()
        stored = record is not None and np.allclose(
            record['correction'].as_list(), value.as_list(), rtol=0, atol=1e-12)
        self.record = record if stored else None
        self.source = self.path if stored else 'parameter'

    def _load(self) -> dict[str, Any] | None:
        self.problem = ''
        try:
            return self._read(self.path)
        except (ValueError, OSError) as exc:
            self.problem = str(exc)
            return None
