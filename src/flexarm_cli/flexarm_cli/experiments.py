"""``flexarm demo``, ``benchmark`` and ``study``: the runs that start their own graph or none."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from flexarm_cli.common import (
    Outcome,
    check_kind,
    check_region,
    show_progress,
    step_printer,
    world_settings,
)
from flexarm_recording.results.outcome_text import (
    Exit,
)


def _experiment(args: argparse.Namespace, **overrides: Any) -> dict[str, Any]:
    import time

    from flexarm_cli.experiment import (
        ExperimentSettings,
        phases_text,
        reserved_domain,
        run_experiment,
        table_text,
    )

    check_kind(args.kind)
    settings = ExperimentSettings(
        name=args.name or time.strftime(f'{args.command}-%Y%m%d-%H%M%S'),
        samples=args.samples, kind=args.kind, real_time_factor=args.rtf,
        record=not args.no_record, seed=args.seed, world=world_settings(args), **overrides)
    with reserved_domain(args.domain_id) as domain:
        summary = run_experiment(settings, domain, progress=show_progress(args))
    print(table_text(summary))
    print(phases_text(summary))
    print(f'results in {summary["results"]}' + (
        f', bag in {summary["bag"]}' if summary['bag'] else '') +
        f'; {summary["seconds"]:.0f} s in all')
    out = {k: v for k, v in summary.items() if k != 'trials'}
    out['ok'] = not summary['nodes_died']
    if not out['ok']:
        raise Outcome(f'node(s) died during the run: {", ".join(summary["nodes_died"])} (their '
                      f'logs are in runs/{settings.name}/)', Exit.FAILED, **out)
    return out


def cmd_demo(args: argparse.Namespace) -> dict[str, Any]:
    """Collect, train and run the paper's Table 10 targets in all three modes."""
    return _experiment(args)


def cmd_benchmark(args: argparse.Namespace) -> dict[str, Any]:
    """Tables 9 and 10 plus held-out random targets, side by side with the paper."""
    return _experiment(args, random_targets=args.random, table9=True)


def cmd_study(args: argparse.Namespace) -> dict[str, Any]:
    """Tables 7 and 8 sensitivity study on the simulator (offline, no graph needed)."""
    check_region(args.region)
    from flexarm_cli.study import QUICK, run_study, table_text, write_study

    overrides = {'region': args.region, 'seeds': args.seeds} | (QUICK if args.quick else {})
    with step_printer('study', args) as progress:
        result = run_study(overrides, progress)
    paths = write_study(result, Path(args.out) / args.region)
    print(table_text(result))
    print(f"written: {', '.join(str(p) for p in paths.values())} "
          f"({result['elapsed_s']:.0f} s)")
    return {'ok': True, **result, **{k: str(v) for k, v in paths.items()}}
