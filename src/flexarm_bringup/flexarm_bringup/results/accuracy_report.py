"""The accuracy study's report for a site engineer (pure): a table in mm, and figures — the
learning curve and the held-out error against its stated bound (matplotlib's object API)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

COLUMNS = ('mean_mm', 'rms_mm', 'p95_mm', 'max_mm', 'coverage', 'sharpness', 'fit_s')


def table_text(report: dict[str, Any]) -> str:
    """The held-out figures of the rigid model and each kind, and the learning curve."""
    head = (f"{report['rows']} rows ({report['skipped_rows']} skipped: missing values; "
            f"{report['rows_outside_limits']} outside the URDF's joint limits), "
            f"{len(report['joints'])} joints to {report['tip']!r}, gravity: {report['gravity']}"
            f"\ntrained on {report['train']} rows, judged on the others, mean of "
            f"{report['splits']} splits (seed {report['seed']})\ntarget "
            f"{report['registration']['target_distance_mm']:.1f} mm from the tip link, at "
            f"{report['registration']['target_offset_mm']} mm in its frame (± "
            f"{report['registration']['target_offset_std_mm']} mm: large where the poses "
            f"cannot tell it from the instrument's frame)")
    lines = [head, '', f"{'model':<14}" + ''.join(f'{c:>11}' for c in COLUMNS)]
    rows = {'rigid': report['rigid']} | report['kinds']
    for name, figures in rows.items():
        lines.append(f'{name:<14}' + ''.join(f'{figures[c]:>11.3f}' for c in COLUMNS))
    if report['curve']:
        lines += ['', 'learning curve (' + next(iter(report['kinds'])) + '): '
                  + ', '.join(f"{p['train']} rows {p['mean_mm']:.3f} mm"
                              for p in report['curve'])]
    return '\n'.join(lines)


def write_figures(report: dict[str, Any], out: Path) -> list[Path]:
    """``learning_curve.png`` (mean and 95th-percentile error, median bound, by training
    rows) in ``out``; nothing when the report has no curve."""
    if not report['curve']:
        return []
    out.mkdir(parents=True, exist_ok=True)
    figure = Figure(figsize=(6, 4), layout='constrained')
    axes = figure.add_subplot()
    sizes = [p['train'] for p in report['curve']]
    for key, label in (('mean_mm', 'mean error'), ('p95_mm', '95th-percentile error'),
                       ('bound_median_mm', 'median stated 95 % bound')):
        axes.plot(sizes, [p[key] for p in report['curve']], marker='o', label=label)
    axes.axhline(report['rigid']['mean_mm'], color='grey', linestyle='--',
                 label='rigid model after registration (mean)')
    axes.set(xscale='log', yscale='log', xlabel='training rows',
             ylabel='held-out 3-D error [mm]',
             title=f"{next(iter(report['kinds']))}: {len(report['joints'])} joints to "
                   f"{report['tip']}")
    axes.grid(True, which='both', alpha=0.3)
    axes.legend()
    path = out / 'learning_curve.png'
    FigureCanvasAgg(figure).print_png(str(path))
    return [path]
