"""The compensator's health on /diagnostics: the model in use, its health per region, the goals
(pure)."""
from __future__ import annotations

from flexarm_core.health_report import ERROR, OK, WARN, Status, status
from flexarm_deflection.model_health import RegionHealth as RegionReport
from flexarm_deflection.model_summary import ModelSummary


def model_status(node: str, info: ModelSummary | None, load_error: str,
                 payload: float | None) -> Status:
    """``<node>: model`` in use: ERROR when an announced model could not be loaded and none
    is in use (PREDICTIVE refuses every goal); WARN when one could not be loaded but the
    previous one stays in use, or the model in use carries a warning (other payload or arm);
    OK otherwise, also without any model (RIGID and CLOSED_LOOP need none)."""
    values = {'version': info.version if info else '', 'kind': info.kind if info else '',
              'dataset': info.dataset if info else '', 'warning': info.warning if info else '',
              'payload [kg]': 'unknown' if payload is None else payload,
              'load error': load_error}
    if info is None:
        if load_error:
            return status(node, 'model', ERROR, load_error, values)
        return status(node, 'model', OK, 'no model announced yet (RIGID and CLOSED_LOOP only)',
                      values)
    text = f'model {info.version} ({info.kind})'
    problem = '; '.join(filter(None, [load_error, info.warning]))
    if problem:
        return status(node, 'model', WARN, f'{text}: {problem}', values)
    return status(node, 'model', OK, f'{text} in use', values)


def model_health_status(node: str, version: str, report: list[RegionReport],
                        stale_residual: float, summary: str) -> Status:
    """``<node>: model health``, the residuals of the model in use per working region: WARN
    when it is stale in a region (refresh it or train anew), else OK."""
    values: dict[str, str | int | float] = {'model': version,
                                            'stale residual [mm]': stale_residual * 1e3}
    for r in report:
        values[f'{r.name} measurements'] = r.observations
        values[f'{r.name} residual median [mm]'] = round(r.median_position * 1e3, 4)
        values[f'{r.name} residual max [mm]'] = round(r.max_position * 1e3, 4)
        values[f'{r.name} stale'] = r.stale
    if summary:
        return status(node, 'model health', WARN, summary, values)
    if not version:
        return status(node, 'model health', OK, 'no model in use', values)
    seen = sum(r.observations for r in report)
    return status(node, 'model health', OK, f'model {version} fits ({seen} recent '
                  'measurements)' if seen else f'model {version}: not measured yet', values)


def goals_status(node: str, counts: dict[str, int], executing: str) -> Status:
    """``<node>: goals``: run, succeeded, failed and canceled since start, and the goal in
    progress. Always OK: a goal that fails tells its client why in its result."""
    run = sum(counts.values())
    values = {'goals run': run, **{f'goals {k}': v for k, v in counts.items()},
              'executing': executing}
    return status(node, 'goals', OK, f'executing {executing}' if executing else
                  f'idle, {run} goals run ({counts.get("succeeded", 0)} succeeded)', values)
