"""Compensator: the ``/move_to_pose`` action server (paper section 3-2, Fig. 4).

RIGID commands the rigid inverse kinematics of the target, PREDICTIVE the fixed point of
``x* = x_d - Delta_N(theta)`` (the paper), CLOSED_LOOP then corrects from the measured tip, and
AUTO chooses by the plan's 95 % bound. The logic is pure: which plan a goal runs and its bound
(:mod:`flexarm_control.execution.planning`), how it runs
(:mod:`flexarm_control.execution.goal_execution`), the bound after the move and online
(:mod:`flexarm_control.execution.bound_check`), the model's health
(:mod:`flexarm_deflection.model_health`). This node validates goals, claims the arm for
each, maps outcomes to error codes, hot-reloads the model the learner announces and publishes
``/compensator/active_model``, ``/compensator/model_health`` and the scene's target and
commanded poses.

Explained in docs/nodes.md#the-compensator-flexarm_compensator.
"""
from __future__ import annotations

import math
import os
import threading
import traceback
from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import PoseStamped
from rclpy.action import ActionServer, CancelResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile
from std_msgs.msg import Float64

from flexarm_control.execution.bound_check import OnlineBound, OnlineSettings
from flexarm_control.execution.compensator import Compensator, Plan
from flexarm_control.execution.compensator_status import (
    goals_status,
    model_health_status,
    model_status,
)
from flexarm_control.execution.goal_bounds import GoalBounds, GoalWatch, goal_error, time_limit
from flexarm_control.execution.goal_execution import (
    CANCELED,
    CONTROLLER_TIMEOUT,
    MEASUREMENT_FAILED,
    SUCCEEDED,
    TOLERANCE_NOT_MET,
    UNREACHABLE,
    GoalSpec,
    execute,
)
from flexarm_control.execution.modes import Mode
from flexarm_control.execution.plan_bound import SiteErrors
from flexarm_control.execution.planning import DataLimits, Planned, Refusal, beyond_data, plan_goal
from flexarm_control.ros.messages import planar
from flexarm_core import topics
from flexarm_core.dds_profile import on_this_machine_only
from flexarm_core.goal_sender import GoalSender, ProcTable, send_goal_writers, sender_at_acceptance
from flexarm_core.health_report import Status
from flexarm_core.kinematics import ArmGeometry, UnreachableError, forward, pose_error
from flexarm_core.regions import regions_from_dict
from flexarm_core.ros.diagnostics import DiagnosticsPublisher
from flexarm_core.ros.node_main import Offload, finish_goal, run
from flexarm_core.ros.node_params import declare, declare_tree
from flexarm_core.ros.scene_msgs import pose_stamped
from flexarm_core.ros.stamps import to_ns
from flexarm_deflection.at_payload import AtPayload
from flexarm_deflection.model_health import HealthSettings, ModelHealth
from flexarm_deflection.model_store import payload_warning
from flexarm_deflection.models import load_model
from flexarm_deflection.predictors import Predictor
from flexarm_motion.arm_motion import ArmMotion, MotionSettings
from flexarm_motion.ros.arm_claim import ArmBusy
from flexarm_motion.ros.arm_interface import ArmInterface
from flexarm_motion.ros.joint_commands import joint_commands
from flexarm_msgs.action import MoveToPose
from flexarm_msgs.msg import GoalOutcome, ModelInfo, RegionHealth
from flexarm_msgs.msg import ModelHealth as HealthMsg

GOAL_THREADS = 2   # the goal executing and one that lost the race past the busy check
Goal = MoveToPose.Goal
Result = MoveToPose.Result
Feedback = MoveToPose.Feedback
REFUSALS = {'no_model': Result.NO_MODEL, 'unreachable': Result.UNREACHABLE,
            'outside_learned_data': Result.OUTSIDE_LEARNED_DATA,
            'bound': Result.BOUND_EXCEEDS_TOLERANCE}
OUTCOMES = {SUCCEEDED: Result.SUCCESSFUL, CANCELED: Result.CANCELED,
            CONTROLLER_TIMEOUT: Result.CONTROLLER_TIMEOUT,
            MEASUREMENT_FAILED: Result.MEASUREMENT_FAILED,
            TOLERANCE_NOT_MET: Result.TOLERANCE_NOT_MET, UNREACHABLE: Result.UNREACHABLE}


def unbound(**fields: Any) -> Result:
    """A result whose plan states no bound (yet): NaN, not a 0 that reads as exact."""
    return Result(position_error_bound=math.nan, angle_error_bound=math.nan, **fields)


def describe(goal: Goal) -> str:
    """A goal as logs and refusals name it: its trial name and mode."""
    mode = Mode(goal.mode).label if goal.mode < len(Mode) else f'mode {goal.mode}'
    return f'{goal.trial or "(no trial name)"} ({mode})'


@dataclass
class GoalPlan:
    """A goal as planned: where it goes, the plan and its execution's spec, the model at the
    payload carried, and the notes its result will carry."""

    target: np.ndarray
    planned: Planned
    spec: GoalSpec
    predictor: AtPayload | None
    notes: list[str]


class CompensatorNode(Node):

    def __init__(self, context: Context | None = None) -> None:
        super().__init__('flexarm_compensator', context=context)
        arm = declare_tree(self, 'arm', 'config/arm.yaml')
        self._geometry = ArmGeometry.from_dict(arm)
        self._compensator = Compensator(self._geometry, declare_tree(
            self, 'compensation', 'config/compensator.yaml'))
        self._pos_tol = declare(self, 'position_tolerance', 'config/compensator.yaml')
        self._ang_tol = declare(self, 'angle_tolerance', 'config/compensator.yaml')
        self._max_corrections = declare(self, 'max_corrections', 'config/compensator.yaml')
        motion_tree = declare_tree(self, 'motion', 'config/motion.yaml')
        motion = MotionSettings.from_dict(motion_tree)
        self._bounds = GoalBounds.nominal()
        reason = self._bounds.tolerance_error(self._pos_tol, self._ang_tol) or (
            None if 1 <= self._max_corrections <= self._bounds.max_corrections else
            f'max_corrections must be 1..{self._bounds.max_corrections}')
        if reason is not None:
            raise ValueError(f'default goal settings out of bounds: {reason}')
        self._limits = DataLimits(declare(self, 'max_data_distance', 'config/compensator.yaml'),
                                  declare(self, 'max_prediction_std', 'config/compensator.yaml'))
        self._site = SiteErrors.from_dict(declare_tree(self, 'error_bound',
                                                       'config/compensator.yaml'))
        model_path = declare(self, 'model_path', 'config/compensator.yaml')
        self._health = ModelHealth(
            HealthSettings.from_dict(declare_tree(self, 'model_health',
                                                  'config/compensator.yaml')),
            regions_from_dict(declare_tree(self, 'regions', 'config/learner.yaml')))
        self._online = OnlineBound(OnlineSettings.from_dict(
            declare_tree(self, 'online_bound', 'config/compensator.yaml')))
        self._health_lock = threading.Lock()     # the model health and the online bound
        self._payload: float | None = None     # [kg] from /payload; None until it comes

        self._group = ReentrantCallbackGroup()   # in parallel under a multi-threaded executor
        self._arm = ArmInterface(self, commands=joint_commands(
            self, motion_tree, arm, lambda: self._payload or 0.0))
        self._motion = ArmMotion(self._arm, self._geometry, motion)
        self._model: tuple[Predictor, ModelInfo] | None = None     # swapped whole
        self._goal_model_version = ''  # of the executing goal's plan (one goal at a time)
        self._load_error = ''          # why the last announced model was not loaded
        self._busy = threading.Lock()
        self._busy_state = threading.Lock()     # _busy taken and _executing set together
        self._goal_counts = {'succeeded': 0, 'failed': 0, 'canceled': 0}
        self._executing = ''           # the goal in progress: trial name, mode and sender
        self._action = topics.absolute(topics.MOVE_TO_POSE, self.get_namespace())
        self._senders: dict[bytes, GoalSender] = {}    # of accepted goals, by goal id, until run
        self._processes = ProcTable()
        self._local = on_this_machine_only(os.environ)    # every client runs on this machine
        self._host: bytes | None = None          # a gid of this node (its host, for senders)
        latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
        self._active_pub = self.create_publisher(ModelInfo, topics.ACTIVE_MODEL, latched)
        self._health_pub = self.create_publisher(HealthMsg, topics.MODEL_HEALTH, latched)
        self.create_subscription(Float64, topics.PAYLOAD, self._on_payload, latched,
                                 callback_group=self._group)
        if model_path:
            self._load_model(model_path, 'start-up')
        self.create_subscription(ModelInfo, topics.MODEL, self._on_model, latched,
                                 callback_group=self._group)
        self._outcomes = self.create_publisher(GoalOutcome, topics.OUTCOMES, 10)
        self._target_pub = self.create_publisher(PoseStamped, topics.TARGET_POSE, latched)
        self._commanded_pub = self.create_publisher(PoseStamped, topics.COMMANDED_POSE, latched)
        self._goals = Offload(self, GOAL_THREADS)
        self._server = ActionServer(
            self, MoveToPose, topics.MOVE_TO_POSE,
            execute_callback=self._goals.wrap(self._execute),
            cancel_callback=lambda _: CancelResponse.ACCEPT,
            handle_accepted_callback=self._on_accepted, callback_group=self._group)
        self._diagnostics = DiagnosticsPublisher(self, self.statuses)

    def statuses(self) -> list[Status]:
        """The node's health (docs/nodes.md): model, model health, goals."""
        name, model = self.get_name(), self._model
        with self._health_lock:
            health = model_health_status(
                name, self._health.version, self._health.report(),
                self._health.settings.stale_residual, self._health_summary())
        return [model_status(name, model[1] if model else None, self._load_error,
                             self._payload),
                health, goals_status(name, dict(self._goal_counts), self._executing)]

    # --- model hot reload -------------------------------------------------------------------
    def _on_model(self, msg: ModelInfo) -> None:
        if self._model is not None and (msg.version == self._model[1].version
                                        or to_ns(msg.stamp)
                                        < to_ns(self._model[1].stamp)):
            return      # the same model, or an announcement older than the one in use
        self._load_model(msg.path, f'version {msg.version}', msg)

    def _load_model(self, path: str, what: str, info: ModelInfo | None = None) -> None:
        try:
            predictor = load_model(path)
        except (OSError, ValueError) as exc:
            self._load_error = f'the model {what} from {path} could not be loaded: {exc}'
            self.get_logger().error(f'{self._load_error}; keeping the previous one')
            return
        self._load_error = ''
        info = info or ModelInfo(version=path, kind=predictor.kind, path=path)
        self._model = (predictor, info)
        self._active_pub.publish(info)
        with self._health_lock:
            self._health.reset(info.version)
            self._online.reset(info.version)
        self._publish_health()
        self.get_logger().info(f'predictor {what} loaded ({predictor.kind}) from {path}')
        if info.warning:
            self.get_logger().warn(f'model {info.version}: {info.warning}')

    def _on_payload(self, msg: Float64) -> None:
        if msg.data != self._payload:
            self.get_logger().info(f'payload now {msg.data:g} kg')
        self._payload = float(msg.data)

    # --- model health -----------------------------------------------------------------------
    def _observe(self, model: AtPayload, joints: np.ndarray, measured: np.ndarray) -> None:
        """File the residual of a measured tip against the model; log a region turning
        stale. Joints beyond the learned data are not filed: the model promised nothing there
        (an extrapolated goal is warned as such), and its miss says nothing of staleness."""
        if beyond_data(model, joints, self._limits)[2]:
            return
        residual = measured - forward(self._geometry, joints) - model.predict(joints)
        with self._health_lock:
            before = set(self._health.stale_regions())
            self._health.observe(measured, joints, residual)
            newly = set(self._health.stale_regions()) - before
            summary = self._health.summary()
        if newly:
            self.get_logger().warn(summary)
        self._publish_health()

    def _health_summary(self, region: str | None = None) -> str:
        """The stale regions (or ``region`` alone) and the online bound's state; call with
        the health lock held."""
        return '; '.join(filter(None, [self._health.summary(region), self._online.summary()]))

    def _account(self, planned: Planned, target: np.ndarray, first: np.ndarray | None) -> None:
        """A goal's first measurement against the bound its PREDICTIVE plan stated."""
        if planned.parts is None or first is None or planned.extrapolated:
            return
        with self._health_lock:
            broken = self._online.broken
            self._online.account(pose_error(target, first), planned.parts, self._site.camera)
            newly = self._online.broken and not broken
            summary = self._online.summary()
        if newly:
            self.get_logger().warn(summary)
        self._publish_health()

    def _publish_health(self) -> None:
        with self._health_lock:
            report, summary = self._health.report(), self._health_summary()
            version, threshold = self._health.version, self._health.settings.stale_residual
            worst = {r.name: self._health.worst_joints(r.name, 4) for r in report}
            online = self._online
            factor, goals, misses, broken = (online.inflation.factor, online.goals,
                                             online.misses, online.broken)
        self._health_pub.publish(HealthMsg(
            stamp=self.get_clock().now().to_msg(), model_version=version,
            stale=any(r.stale for r in report) or broken, summary=summary,
            stale_residual=threshold, bound_factor=float(factor[0]),
            angle_bound_factor=float(factor[1]), bound_goals=goals, bound_misses=misses,
            regions=[RegionHealth(
                name=r.name, observations=r.observations,
                median_position_residual=r.median_position,
                max_position_residual=r.max_position, median_angle_residual=r.median_angle,
                stale=r.stale, worst_joints=worst[r.name].reshape(-1).tolist())
                for r in report]))

    # --- goal policy ------------------------------------------------------------------------
    def _on_accepted(self, handle: ServerGoalHandle) -> None:
        """Note who may have sent the goal (:mod:`flexarm_core.goal_sender`), then run it."""
        if self._host is None:
            self._host = next((bytes(i.endpoint_gid) for i in self.get_publishers_info_by_topic(
                f'{self._action}/_action/status') if i.node_name == self.get_name()
                and i.node_namespace == self.get_namespace()), None)
        sender = sender_at_acceptance(send_goal_writers(self, self._action), self._host,
                                    self._processes, self._local)
        if by_discovery := sender.by_discovery_only():
            self.get_logger().info(
                f'goal {handle.request.trial or "(no trial name)"}: {", ".join(by_discovery)} '
                'known by discovery alone (no process of this machine): its leaving is seen '
                "only once DDS's lease on it ends")
        self._senders[bytes(handle.goal_id.uuid)] = sender
        handle.execute()

    def _sender_left(self, sender: GoalSender) -> bool:
        return sender.gone(send_goal_writers(self, self._action), self._processes.alive)

    # --- execution --------------------------------------------------------------------------
    def _execute(self, handle: ServerGoalHandle) -> Result:
        goal: Goal = handle.request
        sender = self._senders.pop(bytes(handle.goal_id.uuid), GoalSender())
        with self._busy_state:         # the goal that runs is named to the one refused
            won = self._busy.acquire(blocking=False)
            if won:
                self._executing = f'{describe(goal)}, {sender.text()}'
            running = self._executing
        if not won:                    # this server's other goal runs
            result = unbound(error_code=Result.ARM_BUSY, error_string=(
                f'the arm is busy: {self.get_fully_qualified_name()} runs goal {running}; '
                'nothing moved'))
        else:
            try:
                with self._arm.attached(), ExitStack() as arm:
                    result = self._run(handle, goal, sender, arm)
            except ArmBusy as exc:
                result = unbound(error_code=Result.ARM_BUSY, error_string=str(exc))
            except Exception as exc:   # last resort: a reason for the client, never empty
                self.get_logger().error(f'goal failed: {traceback.format_exc()}')
                result = unbound(error_code=Result.INVALID_GOAL,
                                error_string=f'internal error: {type(exc).__name__}: {exc}')
            finally:
                self._executing = ''
                self._busy.release()
        # The outcome goes out before the result: a client that stops the graph once it has
        # its last result (the demo) found its recorder's bag one outcome short.
        self._publish_outcome(goal, result)
        if result.error_code == Result.CANCELED and not handle.is_cancel_requested:
            handle.abort()                # the server ended it: no cancel request to answer
        else:
            finish_goal(handle, result.error_code, Result.CANCELED)
        outcome = {Result.SUCCESSFUL: 'succeeded', Result.CANCELED: 'canceled'}
        self._goal_counts[outcome.get(result.error_code, 'failed')] += 1
        if result.error_code not in (Result.SUCCESSFUL, Result.CANCELED):
            self.get_logger().warn(f'goal aborted ({result.error_code}): {result.error_string}')
        return result

    def _run(self, handle: ServerGoalHandle, goal: Goal, sender: GoalSender, arm: ExitStack
             ) -> Result:
        """Plan; unless refused or a dry run, claim the arm in ``arm`` and move."""
        result = unbound()
        plan = self._plan(handle, goal, result)
        if plan is None:
            return result
        if goal.dry_run:
            result.error_string = '; '.join(filter(None, ['dry run: nothing moved',
                                                          *plan.notes]))
            return result
        return self._move(handle, goal, sender, arm, plan, result)

    def _plan(self, handle: ServerGoalHandle, goal: Goal, result: Result) -> GoalPlan | None:
        """Validate and plan ``goal``, the plan's figures in ``result``; None when refused
        (``result`` says why)."""
        target = np.array([goal.target.x, goal.target.y, goal.target.phi])

        def fail(code: int, reason: str) -> None:
            result.error_code, result.error_string = code, reason

        reason = goal_error(target, goal.mode, goal.position_tolerance, goal.angle_tolerance,
                            goal.max_corrections, self._bounds)
        if reason is not None:
            return fail(Result.INVALID_GOAL, reason)
        loaded, info = self._model or (None, None)
        predictor, unusable = None, ''
        if loaded is not None and loaded.carries_payload and self._payload is None:
            unusable = (f'model {info.version} predicts at the payload the arm carries and no '
                        '/payload has come (`flexarm payload KG`)')
        elif loaded is not None:
            predictor = AtPayload(loaded, self._payload or 0.0)
        if not self._arm.wait_for_joints(5.0):
            return fail(Result.CONTROLLER_TIMEOUT, 'no /joint_states from the controller')
        mode = Mode(goal.mode)
        measuring = mode in (Mode.CLOSED_LOOP, Mode.AUTO)     # the server's default tolerance
        tolerance = (goal.position_tolerance or (self._pos_tol if measuring else 0.0),
                     goal.angle_tolerance or (self._ang_tol if measuring else 0.0))
        self._target_pub.publish(pose_stamped(target, self.get_clock().now().to_msg()))
        self._feedback(handle, 0, Feedback.PHASE_PLANNING, target, None)
        with self._health_lock:
            inflation = self._online.inflation
        try:
            planned = plan_goal(self._compensator, mode, target, predictor, self._limits,
                                goal.allow_extrapolation,
                                trained_payloads=list(info.payloads) if info else [],
                                site=self._site, tolerance=tolerance, inflation=inflation)
        except UnreachableError as exc:
            return fail(Result.UNREACHABLE, str(exc))
        if isinstance(planned, Refusal):
            result.position_error_bound, result.angle_error_bound = planned.bound
            return fail(REFUSALS[planned.code], '; '.join(filter(None, [planned.reason] + (
                [self._load_error, unusable] if planned.code == 'no_model' else []))))
        spec = GoalSpec(target, planned.mode, *tolerance,
                        goal.max_corrections or self._max_corrections, planned.bound,
                        tuple(self._site.camera), mode == Mode.AUTO)
        notes = [planned.note]
        result.model_version = info.version if planned.uses_model else ''
        self._goal_model_version = result.model_version
        if planned.uses_model:
            fit = [info.warning, payload_warning(list(info.payloads),
                                                 loaded.carries_payload,
                                                 predictor.payload)]
            notes.append(f'warning: model {info.version}: {"; ".join(filter(None, fit))}'
                         if any(fit) else '')
        plan = planned.plan
        result.mode_run = int(planned.mode)
        result.position_error_bound, result.angle_error_bound = planned.bound
        result.data_distance = planned.data_distance
        result.prediction_std = planned.prediction_std
        result.compensation_iterations = plan.iterations
        result.predicted_deflection = planar(plan.predicted_deflection)
        result.joint_positions = plan.joints.tolist()
        result.commanded_pose = planar(plan.commanded_pose)
        return GoalPlan(target, planned, spec, predictor, notes)

    def _move(self, handle: ServerGoalHandle, goal: Goal, sender: GoalSender, arm: ExitStack,
              plan: GoalPlan, result: Result) -> Result:
        """Claim the arm in ``arm``, run the plan, and put its outcome in ``result``."""
        target, notes = plan.target, plan.notes
        if any(notes):
            self.get_logger().warn(f'goal {goal.trial or "(no trial name)"}: '
                                   f'{"; ".join(filter(None, notes))}')
        result.motion = arm.enter_context(self._arm.claim.claimed(
            'move', f'MoveToPose {describe(goal)} to x {target[0] * 1e3:.1f} mm, '
            f'y {target[1] * 1e3:.1f} mm, phi {math.degrees(target[2]):.2f} deg', sender.text(),
            within=goal.motion))
        started = self._arm.arm_time()
        watch = GoalWatch(
            time_limit(plan.spec.max_moves, self._geometry, self._motion.settings),
            lambda: (self._arm.arm_time() - started).nanoseconds * 1e-9,
            lambda: self._sender_left(sender))

        def stop() -> bool:
            return handle.is_cancel_requested or watch() or not self._arm.claim.holds()

        def ended_by(reason: str) -> str:
            named = sender.named(send_goal_writers(self, self._action))
            lost = self._arm.claim.lost
            return (f'canceled by the server: {watch.reason}' if watch.reason else
                    f'canceled: {lost}' if lost else 'canceled') + f'; {reason}; {named.text()}'

        if stop():
            result.joint_positions = self._arm.positions().tolist()
            result.error_code = Result.CANCELED
            result.error_string = ended_by('nothing moved')
            return result

        def progress(phase: str, move: int, now: Plan, measured: np.ndarray | None) -> None:
            self._feedback(handle, move, phase, now.commanded_pose, plan.planned, measured,
                           target)

        predictor = plan.predictor
        observe = ((lambda q, measured: self._observe(predictor, q, measured))
                   if predictor is not None else (lambda q, measured: None))
        run = execute(plan.spec, plan.planned.plan, self._motion, self._compensator, stop,
                      progress, observe)
        self._account(plan.planned, target, run.first)
        result.error_code = OUTCOMES[run.status]
        if run.status == SUCCEEDED:
            notes.append(run.reason)
        elif run.status == CANCELED:
            notes.insert(0, ended_by('arm held'))
        else:
            notes.insert(0, run.reason)
        with self._health_lock:
            stale = self._health_summary(self._health.region_of(target))
        notes.append(f'warning: {stale}' if stale else '')
        result.error_string = '; '.join(filter(None, notes))
        result.iterations = run.moves
        positions = run.held_at if run.held_at is not None else run.plan.joints
        result.joint_positions = positions.tolist()
        result.commanded_pose = planar(run.plan.commanded_pose)
        if run.measured is not None:
            result.measured, result.measured_pose = True, planar(run.measured)
            result.position_error, result.angle_error = run.errors(target)
        return result

    def _feedback(self, handle: ServerGoalHandle, iteration: int, phase: str,
                  commanded: np.ndarray, planned: Planned | None,
                  measured: np.ndarray | None = None, target: np.ndarray | None = None,
                  ) -> None:
        fb = Feedback(iteration=iteration, phase=phase, commanded_pose=planar(commanded),
                      position_error_bound=math.nan, angle_error_bound=math.nan)
        if planned is not None:
            fb.data_distance, fb.prediction_std = planned.data_distance, planned.prediction_std
            fb.position_error_bound, fb.angle_error_bound = planned.bound
            fb.model_version = self._goal_model_version
        if measured is not None and target is not None:
            fb.measured, fb.measured_pose = True, planar(measured)
            fb.position_error, fb.angle_error = pose_error(target, measured)
        handle.publish_feedback(fb)
        if phase != Feedback.PHASE_PLANNING:
            self._commanded_pub.publish(pose_stamped(commanded, self.get_clock().now().to_msg()))

    def _publish_outcome(self, goal: Goal, result: Result) -> None:
        now = self.get_clock().now().to_msg()
        self._outcomes.publish(GoalOutcome(
            stamp=TimeMsg(sec=now.sec, nanosec=now.nanosec), trial=goal.trial, mode=goal.mode,
            target=goal.target, commanded_pose=result.commanded_pose,
            predicted_deflection=result.predicted_deflection,
            measured_pose=result.measured_pose, measured=result.measured,
            position_error=result.position_error, angle_error=result.angle_error,
            iterations=result.iterations, data_distance=result.data_distance,
            prediction_std=result.prediction_std,
            position_error_bound=result.position_error_bound,
            angle_error_bound=result.angle_error_bound, mode_run=result.mode_run,
            error_code=result.error_code,
            error_string=result.error_string, model_version=result.model_version))


    def destroy_node(self) -> None:
        self._goals.shutdown()
        self._server.destroy()           # Node.destroy_node leaves actions (and the node) alive
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    run(CompensatorNode, args)


if __name__ == '__main__':
    main()
