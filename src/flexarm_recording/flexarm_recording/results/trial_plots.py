"""The trials figure of a bag's export (``flexarm bag export``: ``trials.png``): every goal's
tip error by mode, with what has no error (failed goals, dry runs) marked apart; plotting lives
with the results, the bag's reading with the recording."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from flexarm_recording.results.trials import CALIBRATION, DRY_RUN
from flexarm_core.atomic_file import atomic_write

# marks along the bottom of the trials figure: (marker, colour) of each kind of row
MARKS = {'failed goals': ('x', 'red'), 'dry runs': ('|', 'tab:blue'),
         'no error recorded': ('|', 'gray')}


def _error_series(rows: Sequence[dict[str, Any]], quantity: str
                  ) -> tuple[dict[str, tuple[list[int], list[float]]], dict[str, list[int]]]:
    """What the plot shows of ``quantity`` (``position_error_mm`` or ``angle_error_deg``).

    Returns ``({mode_name: (row indices, |error|)}, {mark of :data:`MARKS`: row indices})``:
    only succeeded goals with an error (true, else measured) are plotted as errors; dry runs
    have their own mark, calibration moves are left out.
    """
    by_mode: dict[str, tuple[list[int], list[float]]] = {}
    marks: dict[str, list[int]] = {what: [] for what in MARKS}
    for i, row in enumerate(rows):
        value = row.get(f'truth_{quantity}', row.get(f'measured_{quantity}'))
        if row['kind'] == CALIBRATION:
            continue
        if row['kind'] == DRY_RUN:
            marks['dry runs'].append(i)
        elif not row['succeeded']:
            marks['failed goals'].append(i)
        elif value is None:
            marks['no error recorded'].append(i)
        else:
            index, values = by_mode.setdefault(row['mode_name'], ([], []))
            index.append(i)
            values.append(abs(value))
    return by_mode, marks


def trials_figure(rows: Sequence[dict[str, Any]], title: str) -> Figure:
    """Position and |angle| error of every succeeded goal by mode on log axes; goals that
    failed or succeeded without an error, and dry runs, as marks along each axis' bottom;
    no calibration move. The x axis is the row of the CSV."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FormatStrFormatter, MaxNLocator, NullFormatter

    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for ax, quantity, label in ((axes[0], 'position_error_mm', 'position error [mm]'),
                                (axes[1], 'angle_error_deg', '|angle error| [deg]')):
        by_mode, marks = _error_series(rows, quantity)
        for mode, (index, values) in by_mode.items():
            ax.plot(index, values, 'o', label=mode)
        for what, index in marks.items():
            marker, color = MARKS[what]
            if index:
                ax.plot(index, [0.0] * len(index), marker, color=color, markersize=9,
                        transform=ax.get_xaxis_transform(), clip_on=False,
                        label=f'{what}: {len(index)}')
        ax.set_yscale('log')
        ax.yaxis.set_major_formatter(FormatStrFormatter('%g'))
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[1].set_xlabel('goal')
    axes[1].xaxis.set_major_locator(MaxNLocator(integer=True))
    axes[0].set_title(f'{title}: tip error per goal (truth where recorded, else measured)')
    axes[0].legend(fontsize='small')
    fig.tight_layout()
    return fig


def plot_trials(rows: Sequence[dict[str, Any]], png_path: Path, title: str) -> None:
    """Write :func:`trials_figure` of ``rows`` to ``png_path``."""
    import matplotlib.pyplot as plt

    fig = trials_figure(rows, title)
    atomic_write(png_path, lambda f: fig.savefig(f, dpi=100, format='png'))
    plt.close(fig)
