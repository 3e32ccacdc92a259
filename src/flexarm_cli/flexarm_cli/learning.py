"""``flexarm collect``, ``refresh``, ``payload``, ``train`` and ``model``: the learner's side."""
from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path
from typing import Any

from flexarm_bringup.launcher import node_name
from flexarm_cli.common import (
    Outcome,
    check_dataset,
    check_kind,
    check_region,
    check_strategy,
    client_session,
    deg,
    learner_settings,
    mm,
    namespaced_name,
    no_result_text,
    run_interruptible_goal,
    show_progress,
    timed_step,
    usage,
)
from flexarm_core import topics
from flexarm_core.paths import MODELS_DIR
from flexarm_recording.results.outcome_text import (
    COLLECT_HINTS,
    TRAIN_HINT,
    Exit,
    arm_busy_text,
    code_name,
    failure_text,
    human_units,
    is_busy,
)


def _collect_kept(result: Any) -> str:
    return (f'{result.collected} collected, {result.skipped} skipped; {result.total} samples '
            f'in {result.dataset_path}')


def collect_interrupted_text(result: Any) -> str:
    from flexarm_msgs.action import CollectSamples

    if result is None:
        return f'{no_result_text()}; the samples collected before are kept in the dataset'
    if result.error_code != CollectSamples.Result.CANCELED:
        return f'interrupted after the collection had ended: {_collect_kept(result)}'
    return f'cancelled; the samples collected are kept: {_collect_kept(result)}'


def cmd_collect(args: argparse.Namespace) -> dict[str, Any]:
    """Collect N deflection samples with the learner."""
    max_count = learner_settings()['max_count']
    if args.count > max_count:
        raise usage(f'count must be 1..{max_count} (max_count of config/learner.yaml), '
                    f'got {args.count}')
    check_region(args.region)
    check_strategy(args.strategy)
    check_dataset(args.dataset)
    from tqdm import tqdm

    from flexarm_msgs.action import CollectSamples

    with client_session(args, learner=True) as client:
        if args.payload is not None:
            client.set_payload(args.payload)
            print(f'payload declared: {args.payload:g} kg')
        bar = tqdm(total=args.count, unit='sample', desc='collect',
                   disable=not show_progress(args))
        try:
            result = run_interruptible_goal(lambda: client.collect(
                args.count, region=args.region, strategy=args.strategy, seed=args.seed,
                dataset=args.dataset, timeout=args.timeout,
                feedback=lambda fb: bar.update(fb.k - bar.n)),
                namespaced_name(args, topics.COLLECT_SAMPLES), collect_interrupted_text)
        finally:
            bar.close()
    name = code_name(CollectSamples.Result, result.error_code)
    out = {'ok': result.error_code == CollectSamples.Result.SUCCESSFUL,
           'error_code': result.error_code, 'error_name': name,
           'error_string': result.error_string, 'collected': result.collected,
           'skipped': result.skipped, 'total': result.total,
           'dataset_path': result.dataset_path}
    if out['ok']:
        print(_collect_kept(result) + (
            f' ({human_units(result.error_string)})' if result.error_string else ''))
        return out
    if name == 'ARM_BUSY':
        raise Outcome(arm_busy_text(result.error_string), Exit.BUSY, **out)
    moved = name != 'INVALID_GOAL'
    raise Outcome(failure_text(name, result.error_string, COLLECT_HINTS, moved) + (
        f'\n  dataset: {_collect_kept(result)}' if moved else ''), Exit.FAILED, **out)


def cmd_refresh(args: argparse.Namespace) -> dict[str, Any]:
    """Mend a model the health check reports stale from a few new samples."""
    if args.region:
        check_region(args.region)
    from tqdm import tqdm

    from flexarm_msgs.action import RefreshModel

    with client_session(args, learner=True) as client:
        bar = tqdm(unit='sample', desc='refresh', disable=not show_progress(args))

        def show(fb: Any) -> None:
            bar.total = fb.n
            bar.update(fb.k - bar.n)

        try:
            result = run_interruptible_goal(
                lambda: client.refresh(args.count, args.region, args.timeout, show, args.force),
                namespaced_name(args, topics.REFRESH_MODEL),
                lambda r: 'interrupted; the model is unchanged unless the refresh had ended')
        finally:
            bar.close()
    name = code_name(RefreshModel.Result, result.error_code)
    out = {'ok': result.error_code == RefreshModel.Result.SUCCESSFUL,
           'error_code': result.error_code, 'error_name': name,
           'error_string': result.error_string, 'collected': result.collected,
           'dataset_path': result.dataset_path, 'model_version': result.model.version,
           'residual_before': result.residual_before, 'residual_after': result.residual_after}
    if not out['ok']:
        if name == 'ARM_BUSY':
            raise Outcome(arm_busy_text(result.error_string), Exit.BUSY, **out)
        raise Outcome(f'{name}: {human_units(result.error_string)}', Exit.FAILED, **out)
    print(f'model v{result.model.version} announced: the previous one corrected from '
          f'{result.collected} new samples (in {result.dataset_path}); their median residual '
          f'{mm(result.residual_before):.3f} mm before, {mm(result.residual_after):.3f} mm '
          'after')
    return out


def cmd_payload(args: argparse.Namespace) -> dict[str, Any]:
    """Show the payload the arm carries, or declare a new one [kg] (a tool picked up)."""
    note = ''
    with client_session(args, learner=True) as client:
        if args.kg is not None:
            client.set_payload(args.kg)
            note = payload_bounds_note(client, args.kg)
        kg = float(client.node_parameter(node_name('learner'), 'payload'))
    print(f'payload: {kg:g} kg' + (' (declared now)' if args.kg is not None else '')
          + (f'\n  {note}' if note else ''))
    return {'ok': True, 'payload_kg': kg, 'note': note}


def payload_bounds_note(client: Any, kg: float, wait: float = 2.0) -> str:
    """How the error bounds of the model the compensator uses grew at ``kg`` and what brings
    them back (:mod:`flexarm_deflection.payload_bounds`; '' at a trained payload, or
    when this host cannot read the model's file)."""
    from flexarm_core import liveness
    from flexarm_core.kinematics import ArmGeometry
    from flexarm_core.params import load_config
    from flexarm_core.regions import configured_regions
    from flexarm_deflection.models import load_model
    from flexarm_deflection.payload_bounds import bound_report

    deadline = time.monotonic() + liveness.limit(wait)   # the latched announcement, if unheard
    while client.active_model is None and time.monotonic() < deadline:
        client.spin_once(0.05)
    info = client.active_model
    if info is None or not os.path.isfile(info.path):
        return ''
    return bound_report(load_model(info.path), configured_regions(node_name('learner')),
                        ArmGeometry.from_dict(load_config('arm.yaml')['arm']),
                        list(info.payloads), kg)


def cmd_train(args: argparse.Namespace) -> dict[str, Any]:
    """Train a deflection predictor on a dataset; prints the validation metrics."""
    check_kind(args.kind)
    check_dataset(args.dataset)
    what = f'training {args.kind or "the default kind"} on dataset {args.dataset or "default"}'
    with client_session(args, learner=True) as client:
        try:
            with timed_step(what, args):
                response = client.train(args.kind, args.settings, dataset=args.dataset,
                                        timeout=args.timeout)
        except KeyboardInterrupt:
            raise Outcome('interrupted; the learner finishes this training anyway (training '
                          'cannot be cancelled) and announces its model if it succeeds',
                          Exit.INTERRUPTED) from None
    m = response.metrics
    out = {'ok': response.success, 'message': response.message,
           'model_version': response.model_version, 'model_path': response.model_path,
           'metrics': {k: getattr(m, k) for k in (
               'validation', 'samples', 'max_error_x', 'max_error_y', 'max_error_phi',
               'mean_error_x', 'mean_error_y', 'mean_error_phi', 'selected_settings',
               'max_slope', 'bound_coverage', 'angle_bound_coverage')} | {
                   'excluded_samples': list(m.excluded_samples)}}
    if not response.success:
        if is_busy(response.message):
            raise Outcome(response.message, Exit.BUSY, **out)
        raise Outcome(f'{human_units(response.message)}\n  what to do: {TRAIN_HINT}',
                      Exit.FAILED, **out)
    print(f'model v{response.model_version} at {response.model_path} '
          f'(chosen by validation: {m.selected_settings})\n'
          f'{m.validation}, {m.samples} samples: max |error| x {mm(m.max_error_x):.3f} mm, '
          f'y {mm(m.max_error_y):.3f} mm, phi {deg(m.max_error_phi):.4f} deg; mean '
          f'{mm(m.mean_error_x):.3f} mm, {mm(m.mean_error_y):.3f} mm, '
          f'{deg(m.mean_error_phi):.4f} deg\n'
          f'95 % error bounds calibrated on the held-out samples: they covered '
          f'{_share(m.bound_coverage)} of the positions and {_share(m.angle_bound_coverage)} '
          'of the angles of the other half of them')
    if len(m.excluded_samples):
        print(f'excluded as outliers: {len(m.excluded_samples)} sample(s), dataset '
              f'indices {list(m.excluded_samples)}')
    if response.message:
        print(human_units(response.message))
    return out


def _share(value: float) -> str:
    return 'an unknown share (too few poses)' if math.isnan(value) else f'{100 * value:.0f} %'


def cmd_model(args: argparse.Namespace) -> dict[str, Any]:
    """List the trained models (list) or make an earlier one current again (use VERSION)."""
    return _model_list(args) if args.action == 'list' else _model_use(args)


def _model_list(args: argparse.Namespace) -> dict[str, Any]:
    from flexarm_bringup.graph_status import file_summary
    from flexarm_bringup.status_text import model_line
    from flexarm_deflection.model_store import list_models
    from flexarm_deflection.models import model_metadata

    directory = Path(args.models) if args.models else MODELS_DIR / args.namespace
    entries = list_models(directory, model_metadata)
    if not entries:
        print(f'no models in {directory}: collect samples and `flexarm train`')
    rows = []
    for entry in entries:
        mark = '*' if entry.current else ' '
        if entry.metadata is None:
            print(f'{mark} v{entry.version}: unusable: {human_units(entry.problem)}')
            rows.append({'version': str(entry.version), 'current': entry.current,
                         'path': str(entry.path), 'problem': entry.problem})
            continue
        summary = file_summary(str(entry.version), entry.path, entry.metadata)
        print(mark + ' ' + model_line(entry.path.name, summary))
        rows.append(summary | {'current': entry.current})
    if entries:
        print("* = current (announced by the learner; `flexarm status` shows what the "
              "compensator runs)")
    return {'ok': True, 'models': rows}


def _model_use(args: argparse.Namespace) -> dict[str, Any]:
    from flexarm_bringup.graph_status import model_summary
    from flexarm_bringup.status_text import model_line

    if not args.version.isdecimal():
        raise usage('model use needs a version number (see flexarm model list), not '
                    f'{args.version!r}')
    with client_session(args, learner=True) as client:
        response = client.use_model(args.version, timeout=args.wait)
        if not response.success:
            raise Outcome(response.message, Exit.FAILED)
        with timed_step(f'waiting for the compensator to load v{args.version}', args):
            client.wait_for_model(response.model.version, timeout=args.wait)
    summary = model_summary(response.model)
    print(model_line('model driving the arm now', summary))
    return {'ok': True, 'model': summary}
