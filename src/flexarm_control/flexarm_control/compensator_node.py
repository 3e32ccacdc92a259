"""Compensator: the ``/move_to_pose`` action server (seed section 3-2, Fig. 4).

RIGID commands the rigid inverse kinematics of the target; PREDICTIVE commands the fixed point
of ``x* = x_d - Delta_N(theta)`` (the paper); CLOSED_LOOP then measures the tip and corrects
the target from the measured error until within tolerance (beyond the paper). Which plan a
goal runs — PREDICTIVE refused beyond the learned data (``OUTSIDE_LEARNED_DATA``, or run with
a warning if the goal allows extrapolation), CLOSED_LOOP started from the rigid plan without a
usable model — is :mod:`flexarm_control.planning`; every result, feedback and
``/compensator/outcomes`` message carries the plan's distance from the learned data and the
model's std there. The algorithm lives in :mod:`flexarm_control.compensator`; this node
validates goals, moves the arm through :class:`~flexarm_control.arm_interface.ArmInterface`,
reports feedback and results, and hot-reloads the predictor the learner announces on
``/learner/model`` and republishes the one it uses on the latched
``/compensator/active_model``.

Goal policy: one goal at a time; a goal arriving while another executes is rejected. Two goals
arriving together can both pass that check: execution decides, and the one that finds the
other executing is aborted (INVALID_GOAL, "busy") before anything moves. Every accepted goal
is validated before anything moves and aborted with an error code and reason if invalid; an
unexpected error aborts the goal with INVALID_GOAL and "internal error: ...", never with an
empty result. Cancel holds the arm at its current joint positions (the result's
``joint_positions`` are those). A model that takes the payload as an input is refused (the
compensator does not know the payload): the previous one stays active.

Provenance and tolerances: every result, feedback and outcome names the model version its plan
used ("" for a rigid plan); a model announced with a warning (e.g. trained at another payload)
adds it to the result's ``error_string``. RIGID and PREDICTIVE check a tolerance only when the
goal gives one: the measured error must be within it (TOLERANCE_NOT_MET otherwise, and
MEASUREMENT_FAILED if the tip could not be measured to check it). A ``dry_run`` goal is planned
and answered with the plan; nothing moves.

The executor has ``EXECUTOR_THREADS`` threads, so an executing goal (holding one thread until
it ends) leaves threads for joint states, tip poses, cancel and new goals.
"""
from __future__ import annotations

import math
import threading
import traceback
from functools import partial

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile

from flexarm_control import topics
from flexarm_control.arm_interface import ArmInterface
from flexarm_control.compensator import Compensator, Plan
from flexarm_control.kinematics import ArmGeometry, UnreachableError, pose_error
from flexarm_control.node_main import finish_goal, run
from flexarm_control.node_params import declare, declare_tree
from flexarm_control.planning import MODES, DataLimits, Planned, Refusal, plan_goal
from flexarm_control.predictors import Predictor, load_predictor
from flexarm_msgs.action import MoveToPose
from flexarm_msgs.msg import GoalOutcome, ModelInfo, PlanarPose

EXECUTOR_THREADS = 4
Goal = MoveToPose.Goal
Result = MoveToPose.Result
Feedback = MoveToPose.Feedback
REFUSALS = {'no_model': Result.NO_MODEL, 'unreachable': Result.UNREACHABLE,
            'outside_learned_data': Result.OUTSIDE_LEARNED_DATA}


def planar(pose: np.ndarray) -> PlanarPose:
    return PlanarPose(x=float(pose[0]), y=float(pose[1]), phi=float(pose[2]))


def goal_error(goal: Goal) -> str | None:
    """Why a goal is malformed (before any kinematics), or None."""
    values = {'target.x': goal.target.x, 'target.y': goal.target.y,
              'target.phi': goal.target.phi, 'position_tolerance': goal.position_tolerance,
              'angle_tolerance': goal.angle_tolerance}
    bad = [name for name, v in values.items() if not math.isfinite(v)]
    if bad:
        return f'non-finite {", ".join(bad)}'
    if goal.mode >= len(MODES):
        return f'unknown mode {goal.mode}'
    if goal.position_tolerance < 0 or goal.angle_tolerance < 0:
        return 'tolerances must be >= 0 (0 = server default)'
    return None


class CompensatorNode(Node):

    def __init__(self, context: Context | None = None) -> None:
        super().__init__('flexarm_compensator', context=context)
        self._geometry = ArmGeometry.from_dict(declare_tree(self, 'arm', 'config/arm.yaml'))
        self._compensator = Compensator(self._geometry, declare_tree(
            self, 'compensation', 'config/compensator.yaml'))
        self._pos_tol = declare(self, 'position_tolerance', 0.05e-3,
                                '[m] default closed-loop position tolerance')
        self._ang_tol = declare(self, 'angle_tolerance', math.radians(0.005),
                                '[rad] default closed-loop angle tolerance')
        self._max_iter = declare(self, 'max_iterations', 5,
                                 'default closed-loop corrections per goal')
        self._joint_tol = np.array(declare(
            self, 'arrival_tolerance', [1e-4, 1e-5, 1e-4, 1e-4],
            'joint1..joint4 distance to the command that counts as arrived [rad, m, rad, rad]'))
        self._move_margin = declare(self, 'move_timeout_margin', 10.0,
                                    '[s] added to the slowest joint travel time for a timeout')
        self._frames = declare(self, 'measurement_frames', 3,
                               'valid settled tip poses averaged per measurement')
        self._measure_timeout = declare(self, 'measurement_timeout', 30.0,
                                        '[s] wait for a valid settled measurement after a move')
        self._limits = DataLimits(
            declare(self, 'max_data_distance', 3.0, 'PREDICTIVE refuses joints farther than '
                    'this from the learning samples [typical sample spacings]'),
            declare(self, 'max_prediction_std', 0.3e-3, "[m] PREDICTIVE refuses joints where "
                    "the model's std of the predicted tip position exceeds this"))
        model_path = declare(self, 'model_path', '',
                             'predictor loaded at start ("" = wait for /learner/model)')

        self._group = ReentrantCallbackGroup()
        self._arm = ArmInterface(self, self._group)
        self._model: tuple[Predictor, ModelInfo] | None = None     # swapped whole
        self._goal_model_version = ''  # of the executing goal's plan (one goal at a time)
        self._load_error = ''          # why the last announced model was not loaded
        self._busy = threading.Lock()
        latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
        self._active_pub = self.create_publisher(ModelInfo, topics.ACTIVE_MODEL, latched)
        if model_path:
            self._load_model(model_path, 'start-up')
        self.create_subscription(ModelInfo, topics.MODEL, self._on_model, latched,
                                 callback_group=self._group)
        self._outcomes = self.create_publisher(GoalOutcome, topics.OUTCOMES, 10)
        self._server = ActionServer(
            self, MoveToPose, topics.MOVE_TO_POSE, execute_callback=self._execute,
            goal_callback=self._on_goal, cancel_callback=lambda _: CancelResponse.ACCEPT,
            callback_group=self._group)

    # --- model hot reload -------------------------------------------------------------------
    def _on_model(self, msg: ModelInfo) -> None:
        if self._model is None or msg.version != self._model[1].version:
            self._load_model(msg.path, f'version {msg.version}', msg)

    def _load_model(self, path: str, what: str, info: ModelInfo | None = None) -> None:
        try:
            predictor = load_predictor(path)
            if predictor.settings['payload_input']:
                raise ValueError('it takes the payload as an input, which the compensator does '
                                 'not know')
        except (OSError, ValueError) as exc:
            self._load_error = f'the model {what} from {path} could not be loaded: {exc}'
            self.get_logger().error(f'{self._load_error}; keeping the previous one')
            return
        self._load_error = ''
        info = info or ModelInfo(version=path, kind=predictor.kind, path=path)
        self._model = (predictor, info)
        self._active_pub.publish(info)
        self.get_logger().info(f'predictor {what} loaded ({predictor.kind}) from {path}')
        if info.warning:
            self.get_logger().warn(f'model {info.version}: {info.warning}')

    # --- goal policy ------------------------------------------------------------------------
    def _on_goal(self, goal: Goal) -> GoalResponse:
        if self._busy.locked():
            self.get_logger().warn('goal rejected: another goal is executing')
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    # --- execution --------------------------------------------------------------------------
    def _execute(self, handle: ServerGoalHandle) -> Result:
        goal: Goal = handle.request
        if not self._busy.acquire(blocking=False):   # lost a race past _on_goal
            result = Result(error_code=Result.INVALID_GOAL,
                            error_string='busy: another goal is executing (one at a time)')
        else:
            try:
                result = self._run(handle, goal)
            except Exception as exc:   # last resort: a reason for the client, never empty
                self.get_logger().error(f'goal failed: {traceback.format_exc()}')
                result = Result(error_code=Result.INVALID_GOAL,
                                error_string=f'internal error: {type(exc).__name__}: {exc}')
            finally:
                self._busy.release()
        finish_goal(handle, result.error_code, Result.CANCELED)
        if result.error_code not in (Result.SUCCESSFUL, Result.CANCELED):
            self.get_logger().warn(f'goal aborted ({result.error_code}): {result.error_string}')
        self._publish_outcome(goal, result)
        return result

    def _run(self, handle: ServerGoalHandle, goal: Goal) -> Result:
        result = Result()
        target = np.array([goal.target.x, goal.target.y, goal.target.phi])

        def fail(code: int, reason: str) -> Result:
            result.error_code, result.error_string = code, reason
            return result

        reason = goal_error(goal)
        if reason is not None:
            return fail(Result.INVALID_GOAL, reason)
        predictor, info = self._model or (None, None)
        if not self._arm.wait_for_joints(5.0):
            return fail(Result.CONTROLLER_TIMEOUT, 'no /joint_states from the controller')
        pos_tol = goal.position_tolerance or self._pos_tol
        ang_tol = goal.angle_tolerance or self._ang_tol
        max_iter = goal.max_iterations or self._max_iter

        self._feedback(handle, 0, Feedback.PHASE_PLANNING, target, None)
        try:
            planned = plan_goal(self._compensator, MODES[goal.mode], target, predictor,
                                self._limits, goal.allow_extrapolation)
        except UnreachableError as exc:
            return fail(Result.UNREACHABLE, str(exc))
        if isinstance(planned, Refusal):
            return fail(REFUSALS[planned.code], planned.reason + (
                f'; {self._load_error}' if planned.code == 'no_model' and self._load_error
                else ''))
        plan = planned.plan
        notes = [planned.note]
        result.model_version = info.version if planned.uses_model else ''
        self._goal_model_version = result.model_version
        if planned.uses_model:
            notes.append(f'warning: model {info.version}: {info.warning}' if info.warning else '')
        result.error_string = '; '.join(filter(None, notes))
        if result.error_string:
            self.get_logger().warn(f'goal {goal.trial or "(no trial name)"}: '
                                   f'{result.error_string}')
        result.data_distance = planned.data_distance
        result.prediction_std = planned.prediction_std
        result.compensation_iterations = plan.iterations
        result.predicted_deflection = planar(plan.predicted_deflection)
        if goal.dry_run:
            result.joint_positions = plan.joints.tolist()
            result.commanded_pose = planar(plan.commanded_pose)
            result.error_string = '; '.join(filter(None, ('dry run: nothing moved',
                                                          result.error_string)))
            return result

        iteration = 0
        while True:
            iteration += 1
            outcome = self._move_and_measure(handle, plan, iteration, planned)
            result.iterations = iteration
            result.joint_positions = plan.joints.tolist()
            result.commanded_pose = planar(plan.commanded_pose)
            if isinstance(outcome, Result):
                outcome.iterations, outcome.joint_positions = iteration, result.joint_positions
                if outcome.error_code == Result.CANCELED:     # where the arm was held
                    outcome.joint_positions = self._arm.joints.positions.tolist()
                for name in ('commanded_pose', 'predicted_deflection', 'model_version',
                             'compensation_iterations', 'data_distance', 'prediction_std'):
                    setattr(outcome, name, getattr(result, name))
                return outcome
            closed = goal.mode == Goal.MODE_CLOSED_LOOP
            checked = closed or goal.position_tolerance > 0 or goal.angle_tolerance > 0
            if outcome is None:
                if checked:
                    return fail(Result.MEASUREMENT_FAILED,
                                'no valid settled tip pose within '
                                f'{self._measure_timeout:.0f} s after the move'
                                + ('' if closed else ' to check the tolerance'))
                result.error_string = '; '.join(filter(None, (
                    result.error_string, 'moved; no valid settled tip measurement')))
                return result
            result.measured, result.measured_pose = True, planar(outcome)
            result.position_error, result.angle_error = pose_error(target, outcome)
            if not closed:
                return self._check_tolerance(goal, result) if checked else result
            if result.position_error <= pos_tol and result.angle_error <= ang_tol:
                return result
            if iteration > max_iter:
                return fail(Result.TOLERANCE_NOT_MET,
                            f'{result.position_error * 1e3:.3f} mm / '
                            f'{math.degrees(result.angle_error):.4f} deg after {max_iter} '
                            'corrections')
            try:
                plan = self._compensator.correct(plan, target, outcome)
            except UnreachableError as exc:
                return fail(Result.UNREACHABLE, f'correction: {exc}')

    @staticmethod
    def _check_tolerance(goal: Goal, result: Result) -> Result:
        """A RIGID/PREDICTIVE result against the tolerances its goal gave (0: not checked)."""
        missed = []
        if goal.position_tolerance and result.position_error > goal.position_tolerance:
            missed.append(f'position {result.position_error * 1e3:.3f} mm > '
                          f'{goal.position_tolerance * 1e3:.3f} mm')
        if goal.angle_tolerance and result.angle_error > goal.angle_tolerance:
            missed.append(f'angle {math.degrees(result.angle_error):.4f} deg > '
                          f'{math.degrees(goal.angle_tolerance):.4f} deg')
        if missed:
            result.error_code = Result.TOLERANCE_NOT_MET
            result.error_string = '; '.join(filter(None, (
                f'measured error beyond the tolerance: {", ".join(missed)}',
                result.error_string)))
        return result

    def _move_and_measure(self, handle: ServerGoalHandle, plan: Plan, iteration: int,
                          planned: Planned):
        """Move to the plan; the measured pose, None if unmeasured, or a failure Result."""
        self._feedback(handle, iteration, Feedback.PHASE_MOVING, plan.commanded_pose, planned)
        current = self._arm.joints.positions
        travel = np.max(np.abs(plan.joints - current) / self._geometry.velocity)
        arrived = self._arm.move(plan.joints, self._joint_tol, travel + self._move_margin,
                                 abort=lambda: handle.is_cancel_requested)
        if handle.is_cancel_requested:
            self._arm.hold()
            return Result(error_code=Result.CANCELED, error_string='canceled; arm held')
        if not arrived:
            silent = self._arm.controller_silent
            self._arm.hold()
            return Result(error_code=Result.CONTROLLER_TIMEOUT, error_string=(
                'the controller stopped publishing /joint_states mid-move (died, or its link '
                'was lost): the arm\'s state is unknown' if silent else
                f'joints did not reach the command within {travel + self._move_margin:.0f} s'))
        self._feedback(handle, iteration, Feedback.PHASE_SETTLING, plan.commanded_pose,
                       planned)
        measurement = self._arm.measure(self._frames, self._measure_timeout,
                                        abort=lambda: handle.is_cancel_requested)
        if handle.is_cancel_requested:
            return Result(error_code=Result.CANCELED, error_string='canceled after the move')
        if measurement is None:
            return None
        self._feedback(handle, iteration, Feedback.PHASE_MEASURING, plan.commanded_pose,
                       planned, measurement.pose, handle.request)
        return measurement.pose

    def _feedback(self, handle: ServerGoalHandle, iteration: int, phase: str,
                  commanded: np.ndarray, planned: Planned | None,
                  measured: np.ndarray | None = None, goal: Goal | None = None) -> None:
        fb = Feedback(iteration=iteration, phase=phase, commanded_pose=planar(commanded))
        if planned is not None:
            fb.data_distance, fb.prediction_std = planned.data_distance, planned.prediction_std
            fb.model_version = self._goal_model_version
        if measured is not None and goal is not None:
            fb.measured, fb.measured_pose = True, planar(measured)
            fb.position_error, fb.angle_error = pose_error(
                np.array([goal.target.x, goal.target.y, goal.target.phi]), measured)
        handle.publish_feedback(fb)

    def _publish_outcome(self, goal: Goal, result: Result) -> None:
        now = self.get_clock().now().to_msg()
        self._outcomes.publish(GoalOutcome(
            stamp=TimeMsg(sec=now.sec, nanosec=now.nanosec), trial=goal.trial, mode=goal.mode,
            target=goal.target, commanded_pose=result.commanded_pose,
            predicted_deflection=result.predicted_deflection,
            measured_pose=result.measured_pose, measured=result.measured,
            position_error=result.position_error, angle_error=result.angle_error,
            iterations=result.iterations, data_distance=result.data_distance,
            prediction_std=result.prediction_std, error_code=result.error_code,
            error_string=result.error_string, model_version=result.model_version))


    def destroy_node(self) -> None:
        self._server.destroy()           # Node.destroy_node leaves actions (and the node) alive
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    run(CompensatorNode, args, partial(MultiThreadedExecutor, num_threads=EXECUTOR_THREADS))


if __name__ == '__main__':
    main()
