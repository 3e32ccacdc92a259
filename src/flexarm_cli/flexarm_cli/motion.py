"""``flexarm move`` and ``flexarm cancel``: a goal to the arm, said in mm and degrees."""
from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from flexarm_cli.common import (
    Outcome,
    client_session,
    deg,
    mm,
    namespaced_name,
    no_result_text,
    pose_dict,
    run_interruptible_goal,
    show_progress,
    timed_step,
)
from flexarm_cli.learning import collect_interrupted_text
from flexarm_control.execution.modes import Mode
from flexarm_core import topics
from flexarm_recording.results.outcome_text import (
    MOVE_HINTS,
    Exit,
    arm_busy_text,
    code_name,
    failure_text,
    human_units,
    pose_text,
)


def _measured_text(pose: Any, position_error: float, angle_error: float) -> str:
    return (f'measured {pose_text((pose.x, pose.y, pose.phi))}; error '
            f'{mm(position_error):.3f} mm, {deg(angle_error):.4f} deg')


def _show_feedback(fb: Any) -> None:
    """A goal's feedback line: progress, so on stderr (stdout holds the result only)."""
    measured = (' ' + _measured_text(fb.measured_pose, fb.position_error, fb.angle_error)
                if fb.measured else '')
    print(f'  [{fb.iteration}] {fb.phase}{measured}', file=sys.stderr, flush=True)


def _bound_text(result: Any) -> str:
    """The plan's 95 % error bound, stated before it moved."""
    if math.isnan(result.position_error_bound):
        return ('; no error bound stated (the model was fitted without the learner\'s '
                'held-out calibration)')
    return (f'; expected within {mm(result.position_error_bound):.3f} mm, '
            f'{deg(result.angle_error_bound):.4f} deg (95 %)')


def _move_text(result: Any) -> str:
    """A MoveToPose result in words: reached (how well), refused or failed (why). A RIGID
    goal only 'moved (uncompensated)': it makes no promise of accuracy to reach."""
    from flexarm_msgs.action import MoveToPose

    if result.error_code != MoveToPose.Result.SUCCESSFUL:
        return failure_text(code_name(MoveToPose.Result, result.error_code),
                            result.error_string, MOVE_HINTS, moved=result.iterations > 0)
    if result.iterations == 0:                  # a dry run: the plan, nothing moved
        return _plan_text(result)
    rigid = result.mode_run == Mode.RIGID
    verb = 'moved (uncompensated)' if rigid else 'reached' if result.measured else 'moved'
    reached = f'{verb} in {result.iterations} move(s)' + (': ' + _measured_text(
        result.measured_pose, result.position_error, result.angle_error) if result.measured
        else ', not measured') + ('' if rigid else f' ({_model_text(result.model_version)})'
                                  ) + _bound_text(result)
    learned = (_learned_text(result.data_distance, result.prediction_std)
               if result.data_distance or result.prediction_std else '')
    notes = f'; {human_units(result.error_string)}' if result.error_string else ''
    return reached + learned + notes


def _model_text(version: str) -> str:
    return f'model v{version}' if version else 'rigid plan, no model'


def _learned_text(distance: float, std: float) -> str:
    """How far from the learned data a plan lies; the model's std only where it has one
    (GP: > 0; kinds without a posterior give 0, which is no claim of certainty)."""
    return (f'; {distance:.2f} sample spacings from the learned data'
            + (f', model std {mm(std):.3f} mm' if std > 0 else ''))


def _plan_text(result: Any) -> str:
    """A dry run's plan: what would be commanded, and from which model."""
    q, d, c = result.joint_positions, result.predicted_deflection, result.commanded_pose
    learned = (_learned_text(result.data_distance, result.prediction_std)
               if result.model_version else '')
    notes = human_units(result.error_string.replace('dry run: nothing moved', '').strip('; '))
    return (f'plan ({_model_text(result.model_version)}; nothing moved): command '
            f'{pose_text((c.x, c.y, c.phi))} to the rigid model, joints {deg(q[0]):.3f} deg, '
            f'{mm(q[1]):.2f} mm, {deg(q[2]):.3f} deg, {deg(q[3]):.3f} deg; predicted '
            f'deflection {mm(d.x):.3f} mm, {mm(d.y):.3f} mm, {deg(d.phi):.4f} deg'
            + _bound_text(result) + learned + (f'; {notes}' if notes else ''))


def _move_interrupted(result: Any) -> str:
    """Where a cancelled goal left the arm: the rigid pose of the joints it stopped at."""
    import numpy as np

    from flexarm_core.kinematics import ArmGeometry, forward
    from flexarm_core.params import load_config
    from flexarm_msgs.action import MoveToPose

    if result is None:
        return f'{no_result_text()}: where the arm stopped is unknown'
    if result.error_code != MoveToPose.Result.CANCELED:
        return f'interrupted after the goal had ended: {_move_text(result)}'
    geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
    pose = forward(geometry, np.array(result.joint_positions))
    return f'cancelled; arm stopped at {pose_text(pose)} (rigid kinematics of its joints)'


def cmd_move(args: argparse.Namespace) -> dict[str, Any]:
    """Move the tip to X Y PHI [mm mm deg]."""
    from flexarm_msgs.action import MoveToPose

    feedback = _show_feedback if show_progress(args) else None
    with client_session(args, learner=False) as client:
        result = run_interruptible_goal(lambda: client.move_to(
            args.x / 1e3, args.y / 1e3, math.radians(args.phi), mode=args.mode,
            position_tolerance=args.position_tolerance / 1e3,
            angle_tolerance=math.radians(args.angle_tolerance),
            max_corrections=args.max_corrections, trial=args.trial, timeout=args.timeout,
            allow_extrapolation=args.allow_extrapolation, dry_run=args.dry_run,
            feedback=feedback),
            namespaced_name(args, topics.MOVE_TO_POSE), _move_interrupted)
    out = {'ok': result.error_code == MoveToPose.Result.SUCCESSFUL,
           'error_code': result.error_code,
           'error_name': code_name(MoveToPose.Result, result.error_code),
           'error_string': result.error_string, 'mode': args.mode,
           'target': {'x': args.x / 1e3, 'y': args.y / 1e3, 'phi': math.radians(args.phi)},
           'joint_positions': list(result.joint_positions),
           'commanded_pose': pose_dict(result.commanded_pose),
           'predicted_deflection': pose_dict(result.predicted_deflection),
           'measured': result.measured, 'measured_pose': pose_dict(result.measured_pose),
           'position_error': result.position_error, 'angle_error': result.angle_error,
           'iterations': result.iterations,
           'compensation_iterations': result.compensation_iterations,
           'data_distance': result.data_distance, 'prediction_std': result.prediction_std,
           'position_error_bound': result.position_error_bound,
           'angle_error_bound': result.angle_error_bound,
           'mode_run': Mode(result.mode_run).label,
           'model_version': result.model_version, 'dry_run': args.dry_run}
    if not out['ok']:
        if out['error_name'] == 'ARM_BUSY':
            raise Outcome(arm_busy_text(result.error_string), Exit.BUSY, **out)
        raise Outcome(_move_text(result), Exit.FAILED, **out)
    print(_move_text(result))
    return out


def _cancelled_text(goal: Any) -> str:
    """What ``flexarm cancel`` ended: the goal, who sent it and what its result says."""
    who = (f'sent by {goal.sender}' if goal.sender else
           'its server does not record who sent it; clients of the action now: '
           + (', '.join(goal.clients) or 'none'))
    if goal.result is None:
        text = no_result_text()
    else:
        words = {topics.MOVE_TO_POSE: _move_interrupted, topics.COLLECT_SAMPLES:
                 collect_interrupted_text, topics.REFRESH_MODEL: lambda r: 'cancelled; the model '
                 'is unchanged'}
        name = next(n for n in words if goal.action.endswith('/' + n))
        text = words[name](goal.result.result)
    return f'{goal.action} goal {goal.goal_id[:8]} ({who}): {text}'


def cmd_cancel(args: argparse.Namespace) -> dict[str, Any]:
    """Cancel whatever goal runs on the arm (move, collect, refresh), whoever sent it, then
    end the motion that still holds the arm (e.g. a calibration between its poses)."""
    with client_session(args, learner=False) as client:
        with timed_step('cancelling', args):
            goals = client.cancel_all(timeout=args.wait)
            ended = client.end_motion()
    rows = [{'action': g.action, 'goal_id': g.goal_id, 'sender': g.sender,
             'clients': g.clients, 'error_code': None if g.result is None else
             g.result.result.error_code, 'error_string': None if g.result is None else
             g.result.result.error_string} for g in goals]
    if not goals and not ended:
        raise Outcome('nothing to cancel: no goal runs on '
                      f'{namespaced_name(args, topics.MOVE_TO_POSE)} or the learner, and no '
                      'motion holds the arm', Exit.NOTHING_TO_CANCEL, cancelled=rows, motion='')
    for goal in goals:
        print(_cancelled_text(goal))
    if ended:
        print(f'arm motion {ended}')
    return {'ok': True, 'cancelled': rows, 'motion': ended}
