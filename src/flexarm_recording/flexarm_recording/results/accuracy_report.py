"""The accuracy study's report for a site engineer (pure): a table in mm, and figures — the
learning curve and the held-out error against its stated bound (matplotlib's object API)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

# (column, key of the report, scale): lengths shown in mm
COLUMNS = (('mean_mm', 'mean_m', 1e3), ('rms_mm', 'rms_m', 1e3), ('p95_mm', 'p95_m', 1e3),
           ('max_mm', 'max_m', 1e3), ('coverage', 'coverage', 1.0),
           ('sharpness', 'sharpness', 1.0), ('fit_s', 'fit_s', 1.0))
# where the file gives the target's orientation: the predicted one's angle from it, in mrad
ANGLES = (('angle_mrad', 'angle_mean_rad', 1e3), ('max_mrad', 'angle_max_rad', 1e3))


def table_text(report: dict[str, Any]) -> str:
    """The held-out figures of the rigid model and each kind, and the learning curve."""
    registration = report['registration']
    head = (f"{report['rows']} rows ({report['skipped_rows']} skipped: missing values; "
            f"{report['rows_outside_limits']} outside the URDF's joint limits), "
            f"{len(report['joints'])} joints to {report['tip']!r}, gravity: {report['gravity']}"
            f"\ntrained on {report['train']} rows, judged on the others, mean of "
            f"{report['splits']} splits (seed {report['seed']})\ntarget "
            f"{1e3 * registration['target_distance_m']:.1f} mm from the tip link, at "
            f"{_mm(registration['target_offset_m'])} mm in its frame (± "
            f"{_mm(registration['target_offset_std_m'])} mm: large where the poses cannot "
            "tell it from the instrument's frame)")
    rows = {'rigid': report['rigid']} | report['kinds']
    columns = COLUMNS + (ANGLES if 'angle_mean_rad' in report['rigid'] else ())
    lines = [head, '', f"{'model':<14}" + ''.join(f'{c:>11}' for c, _, _ in columns)]
    for name, figures in rows.items():
        lines.append(f'{name:<14}' + ''.join(f'{scale * figures[key]:>11.3f}'
                                             for _, key, scale in columns))
    for kind, chosen in report['chosen'].items():
        lines.append(f"{kind} chose, split by split: {', '.join(chosen)}")
    if report['curve']:
        lines += ['', 'learning curve (' + next(iter(report['kinds'])) + '): '
                  + ', '.join(f"{p['train']} rows {1e3 * p['mean_m']:.3f} mm"
                              for p in report['curve'])]
    return '\n'.join(lines)


def _mm(values: list[float]) -> list[float]:
    return [round(1e3 * v, 3) for v in values]


def write_figures(report: dict[str, Any], out: Path) -> list[Path]:
    """``learning_curve.png`` (mean and 95th-percentile error, median bound, by training
    rows) in ``out``; nothing when the report has no curve."""
    if not report['curve']:
        return []
    out.mkdir(parents=True, exist_ok=True)
    figure = Figure(figsize=(6, 4), layout='constrained')
    axes = figure.add_subplot()
    sizes = [p['train'] for p in report['curve']]
    for key, label in (('mean_m', 'mean error'), ('p95_m', '95th-percentile error'),
                       ('bound_median_m', 'median stated 95 % bound')):
        axes.plot(sizes, [1e3 * p[key] for p in report['curve']], marker='o', label=label)
    axes.axhline(1e3 * report['rigid']['mean_m'], color='grey', linestyle='--',
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
