"""The coded hole plate (pure): hole centres, diameters and the absolute code.

Holes sit on a square grid of ``pitch`` (the paper's 50 mm); hole (i, j) is at
``origin + pitch (i, j)``, i along +x (columns), j along +y (rows). Every hole carries one
symbol of a 4-ary code, its diameter: symbol 0 is the paper's standard 5 mm hole, symbols 1..3
are larger "representative" holes. The code is designed (:func:`design_code`) so that
every 3 x 3 block of holes, read in any of the four 90-degree orientations, occurs only once
on the plate; a camera view that always contains a whole 3 x 3 block therefore identifies the
absolute hole indices and the quarter-turn of the tool angle.

Run ``python -m flexarm_vision.plate --columns C --rows R --seed S`` to print a new code for
config/camera.yaml (top row first, as the plate is seen from the arm).
"""
from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

SYMBOLS = 4       # quaternary code: one of four hole diameters
WINDOW = 3        # side of the hole block that is unique on the plate


class PlateLayout:
    """Hole grid of the plate with its absolute code."""

    def __init__(self, pitch: float, origin: Sequence[float], diameters: Sequence[float],
                 symbols: np.ndarray) -> None:
        diameters = tuple(float(d) for d in diameters)
        if pitch <= 0 or len(diameters) != SYMBOLS or min(diameters) <= 0:
            raise ValueError(f'plate needs a positive pitch and {SYMBOLS} positive diameters')
        if list(diameters) != sorted(diameters) or max(diameters) >= pitch:
            raise ValueError('hole diameters must increase and stay below the pitch')
        symbols = np.asarray(symbols, dtype=np.int8)
        if symbols.ndim != 2 or min(symbols.shape) < WINDOW:
            raise ValueError(f'code must be a 2-D array of at least {WINDOW}x{WINDOW} holes')
        if symbols.min() < 0 or symbols.max() >= SYMBOLS:
            raise ValueError(f'code symbols must be 0..{SYMBOLS - 1}')
        self.pitch = float(pitch)
        self.origin = np.asarray(origin, dtype=float).reshape(2)
        self.diameters = diameters
        self.symbols = symbols            # [i, j]: column i (x), row j (y)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> PlateLayout:
        """From the ``plate.*`` tree of config/camera.yaml (code rows top first)."""
        rows = [str(r) for r in d['code']]
        if len({len(r) for r in rows}) != 1:
            raise ValueError('plate.code rows must all have the same length')
        grid = np.array([[int(c) for c in r] for r in reversed(rows)], dtype=np.int8)
        return cls(float(d['pitch']), d['origin'], d['diameters'], grid.T)

    @property
    def shape(self) -> tuple[int, int]:
        """(columns, rows)."""
        return self.symbols.shape  # type: ignore[return-value]

    def centre(self, i: int | np.ndarray, j: int | np.ndarray) -> np.ndarray:
        """Centre(s) of hole(s) (i, j) [m]; arrays give (N, 2)."""
        return self.origin + self.pitch * np.stack([i, j], axis=-1).astype(float)

    def holes_near(self, point: Sequence[float], radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Grid indices (N, 2) and centres (N, 2) of holes within ``radius`` of ``point``."""
        lo = np.floor((np.asarray(point) - radius - self.origin) / self.pitch).astype(int)
        hi = np.ceil((np.asarray(point) + radius - self.origin) / self.pitch).astype(int)
        lo = np.maximum(lo, 0)
        hi = np.minimum(hi, np.array(self.shape) - 1)
        if np.any(hi < lo):
            return np.zeros((0, 2), int), np.zeros((0, 2))
        ii, jj = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1),
                             indexing='ij')
        index = np.column_stack([ii.ravel(), jj.ravel()])
        centres = self.centre(index[:, 0], index[:, 1])
        near = np.hypot(*(centres - point).T) <= radius
        return index[near], centres[near]


def window_keys(symbols: np.ndarray) -> np.ndarray:
    """Integer key of every WINDOW x WINDOW block in each of its 4 quarter-turns.

    Shape (4, columns - WINDOW + 1, rows - WINDOW + 1); equal keys mean equal blocks.
    """
    blocks = sliding_window_view(np.asarray(symbols, dtype=np.int64), (WINDOW, WINDOW))
    weights = SYMBOLS ** np.arange(WINDOW * WINDOW).reshape(WINDOW, WINDOW)
    return np.stack([np.einsum('ijab,ab->ij', np.rot90(blocks, k, axes=(2, 3)), weights)
                     for k in range(4)])


def code_conflicts(symbols: np.ndarray) -> int:
    """Number of (block, quarter-turn) readings that are not unique on the plate."""
    keys = window_keys(symbols).ravel()
    counts = np.bincount(keys, minlength=SYMBOLS ** (WINDOW * WINDOW))
    return int(np.sum(counts[keys] > 1))


def design_code(columns: int, rows: int, seed: int, max_steps: int = 200_000) -> np.ndarray:
    """A code [i, j] whose blocks are unique in every orientation (local search).

    Starts from a random code and changes one symbol of a conflicting block at a time,
    keeping changes that do not increase the conflict count. Raises if it does not converge.
    """
    rng = np.random.default_rng(seed)
    symbols = rng.integers(0, SYMBOLS, size=(columns, rows)).astype(np.int8)
    conflicts = code_conflicts(symbols)
    for _ in range(max_steps):
        if conflicts == 0:
            return symbols
        keys = window_keys(symbols)
        counts = np.bincount(keys.ravel(), minlength=SYMBOLS ** (WINDOW * WINDOW))
        _, bi, bj = np.nonzero(counts[keys] > 1)
        pick = rng.integers(len(bi))
        i = bi[pick] + rng.integers(WINDOW)
        j = bj[pick] + rng.integers(WINDOW)
        old = symbols[i, j]
        symbols[i, j] = (old + rng.integers(1, SYMBOLS)) % SYMBOLS
        trial = code_conflicts(symbols)
        if trial <= conflicts:
            conflicts = trial
        else:
            symbols[i, j] = old
    raise RuntimeError(f'no conflict-free code after {max_steps} steps')


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description='print a plate code for config/camera.yaml')
    parser.add_argument('--columns', type=int, required=True)
    parser.add_argument('--rows', type=int, required=True)
    parser.add_argument('--seed', type=int, default=0)
    args = parser.parse_args(argv)
    symbols = design_code(args.columns, args.rows, args.seed)
    print('      code:')
    for j in reversed(range(args.rows)):
        print('        - "' + ''.join(str(s) for s in symbols[:, j]) + '"')


if __name__ == '__main__':
    main()
