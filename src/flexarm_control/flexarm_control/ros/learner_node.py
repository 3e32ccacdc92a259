"""Learner: collects deflection samples and trains the predictor (paper section 2-1 steps 2-3).

Offers the ``/collect_samples`` and ``/learner/refresh`` actions and the ``/train`` and
``/learner/use_model`` services; announces the current model on the latched ``/learner/model``
and the ``payload`` parameter on the latched ``/payload``; publishes every sample on
``/learner/samples``. While it moves the arm (claimed from the arm owner) it commands the
controller and takes ``/joint_states`` and ``/tip_pose``; a refresh reads the compensator's
``/compensator/model_health``. The logic is pure: the collection loop
:mod:`flexarm_control.execution.collection`, its poses :mod:`flexarm_deflection.sampling`
and :mod:`~flexarm_deflection.active_sampling`, training
:mod:`flexarm_deflection.training` (in a worker process), the model record
:mod:`flexarm_deflection.model_store` and :mod:`flexarm_deflection.refresh`.

Explained in docs/nodes.md#the-learner-flexarm_learner.
"""
from __future__ import annotations

import json
import threading
import traceback
from collections.abc import Callable, Iterable
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import ExitStack
from pathlib import Path

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionServer, CancelResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSDurabilityPolicy, QoSProfile
from std_msgs.msg import Float64

from flexarm_control.execution.collection import Collected, Collector
from flexarm_control.ros.messages import planar
from flexarm_core import topics
from flexarm_core.goal_sender import ProcTable, send_goal_writers, sender_at_acceptance
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.paths import repo_path
from flexarm_core.regions import Region, regions_from_dict
from flexarm_core.ros.diagnostics import DiagnosticsPublisher
from flexarm_core.ros.node_main import Offload, finish_goal, run
from flexarm_core.ros.node_params import declare, declare_tree
from flexarm_deflection.active_sampling import ActivePoses
from flexarm_deflection.cross_validation import Screening
from flexarm_deflection.dataset import (
    DatasetWriter,
    Sample,
    dataset_name_error,
    load_dataset,
)
from flexarm_deflection.learner_status import learner_statuses
from flexarm_deflection.model_store import (
    DamagedRecord,
    arm_fingerprint,
    find_model,
    fit_warning,
    next_version,
    read_current,
    unloadable_text,
    write_current,
)
from flexarm_deflection.models import load_model, make_model
from flexarm_deflection.payload_bounds import bound_report, needs_retraining
from flexarm_deflection.payload_record import payload_path, read_payload, write_payload
from flexarm_deflection.predictors import Predictor
from flexarm_deflection.refresh import refresh_poses, refresh_regions, refreshed
from flexarm_deflection.sampling import STRATEGIES, sample_poses, travel_order
from flexarm_deflection.training import TrainingWorker
from flexarm_deflection.training_job import train_and_save, warm_up
from flexarm_motion.arm_motion import ArmMotion, MotionSettings
from flexarm_motion.ros.arm_claim import ArmBusy
from flexarm_motion.ros.arm_interface import ArmInterface
from flexarm_motion.ros.joint_commands import joint_commands
from flexarm_msgs.action import CollectSamples, RefreshModel
from flexarm_msgs.msg import (
    DeflectionSample,
    ModelHealth,
    ModelInfo,
    PredictionMetrics,
)
from flexarm_msgs.srv import Train, UseModel

GOAL_THREADS = 2   # the collection or refresh running and one refused meanwhile
CHOICE_TIMEOUT = 60.0    # [s, wall] for the choice of an active learning pose
Goal = CollectSamples.Goal
Result = CollectSamples.Result
Feedback = CollectSamples.Feedback


class LearnerNode(Node):

    def __init__(self) -> None:
        super().__init__('flexarm_learner')
        arm = declare_tree(self, 'arm', 'config/arm.yaml')
        self._geometry = ArmGeometry.from_dict(arm)
        self._arm_id = arm_fingerprint(arm)
        self._regions = regions_from_dict(declare_tree(self, 'regions', 'config/learner.yaml'))
        retries = self._declare_collection()
        self._declare_training()
        motion_tree = declare_tree(self, 'motion', 'config/motion.yaml')
        self._collecting = threading.Lock()
        self._arm = ArmInterface(self, commands=joint_commands(
            self, motion_tree, arm, lambda: self._payload))
        self._collector = Collector(
            ArmMotion(self._arm, self._geometry, MotionSettings.from_dict(motion_tree)),
            self._geometry, retries, clock=lambda: self.get_clock().now().nanoseconds * 1e-9,
            warn=self.get_logger().warn)
        latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
        self._model_pub = self.create_publisher(ModelInfo, topics.MODEL, latched)
        self._restore_payload()
        self._payload_pub = self.create_publisher(Float64, topics.PAYLOAD, latched)
        self._payload_pub.publish(Float64(data=float(self._payload)))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._health: ModelHealth | None = None
        self.create_subscription(ModelHealth, topics.MODEL_HEALTH,
                                 lambda msg: setattr(self, '_health', msg), latched)
        self._sample_pub = self.create_publisher(DeflectionSample, topics.SAMPLES, 100)
        self._serve()
        self._progress = ''        # of the running collection or refresh
        self._training = False
        self._dataset: tuple[str, int] | None = None    # last collected into, its samples
        self._trained: tuple[bool, str] | None = None   # last training: succeeded, outcome
        self._announced: ModelInfo | None = None
        self._announce_error = ''
        self._announce_current()
        self._diagnostics = DiagnosticsPublisher(self, lambda: learner_statuses(
            self.get_name(), self._progress, self._training, self._dataset, self._trained,
            self._announced, self._announce_error))

    def _declare_collection(self) -> int:
        """Where samples and models go, the payload and the collection's defaults
        (config/learner.yaml); the measurement retries."""
        self._data_dir = repo_path(declare(self, 'data_directory', 'config/learner.yaml'))
        self._model_dir = repo_path(declare(self, 'model_directory', 'config/learner.yaml'))
        self._default_dataset = declare(self, 'default_dataset', 'config/learner.yaml')
        self._payload = declare(self, 'payload', 'config/learner.yaml')
        self._refresh_samples = declare(self, 'refresh_samples', 'config/learner.yaml')
        self._default_region = declare(self, 'default_region', 'config/learner.yaml')
        if self._default_region not in self._regions:
            raise ValueError(f'default_region {self._default_region} is not in regions')
        self._default_strategy = declare(self, 'default_strategy', 'config/learner.yaml')
        self._max_count = declare(self, 'max_count', 'config/learner.yaml')
        self._coverage = np.array(declare(self, 'coverage_margin', 'config/learner.yaml'))
        return declare(self, 'measurement_retries', 'config/learner.yaml')

    def _declare_training(self) -> None:
        """The training's defaults, screening and time limit (config/learner.yaml), and the
        worker that trains."""
        self._default_kind = declare(self, 'default_kind', 'config/learner.yaml')
        self._folds = declare(self, 'validation_folds', 'config/learner.yaml')
        self._screening = Screening.from_dict(
            declare_tree(self, 'training', 'config/learner.yaml'))
        self._train_timeout = declare(self, 'training_timeout', 'config/learner.yaml')
        self._trainer = TrainingWorker(warm_up)
        self._chooser = ThreadPoolExecutor(1)   # waits on the worker for active poses

    def _serve(self) -> None:
        """The actions (collect, refresh) and the services (train, use a model)."""
        self._goals = Offload(self, GOAL_THREADS)
        self._collect_server = ActionServer(
            self, CollectSamples, topics.COLLECT_SAMPLES,
            execute_callback=self._goals.wrap(self._collect),
            cancel_callback=lambda _: CancelResponse.ACCEPT)
        self._refresh_server = ActionServer(
            self, RefreshModel, topics.REFRESH_MODEL,
            execute_callback=self._goals.wrap(self._refresh),
            cancel_callback=lambda _: CancelResponse.ACCEPT)
        # One model change at a time: a service awaiting its call holds its callback group.
        models, self._models = MutuallyExclusiveCallbackGroup(), Offload(self, 1)
        self.create_service(Train, topics.TRAIN, self._models.wrap(self._train),
                            callback_group=models)
        self.create_service(UseModel, topics.USE_MODEL, self._models.wrap(self._use_model),
                            callback_group=models)

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """A new ``payload`` [kg]: stored with the next samples and published on /payload."""
        for param in params:
            if param.name != 'payload':
                continue
            value = param.value
            if (param.type_ not in (Parameter.Type.DOUBLE, Parameter.Type.INTEGER)
                    or not 0 <= float(value) < float('inf')):
                return SetParametersResult(successful=False,
                                           reason='payload: a finite number >= 0 [kg]')
            try:
                write_payload(self._model_dir, float(value))
            except OSError as exc:
                return SetParametersResult(successful=False, reason=(
                    f'payload not declared: {payload_path(self._model_dir)} could not be '
                    f'written ({exc})'))
            self._payload = float(value)
            self._payload_pub.publish(Float64(data=self._payload))
            report = self._bound_report()
            self.get_logger().info(f'payload now {self._payload:g} kg' + (
                f': {report}' if report else ''))
        return SetParametersResult(successful=True)

    def _bound_report(self) -> str:
        """How the current model's bounds grew at the payload declared ('' if it was
        trained there, or there is no model to say it of)."""
        try:
            current = read_current(self._model_dir)
            if current is None:
                return ''
            predictor = load_model(current['path'])
        except (DamagedRecord, ValueError, OSError) as exc:
            return f'the current model cannot be read to say its bounds there ({exc})'
        origin = predictor.metadata.get('provenance') or {}
        return bound_report(predictor, self._regions, self._geometry,
                            origin.get('payloads', []), self._payload)

    def _restore_payload(self) -> None:
        """Take the last declared payload over the configured one: the arm still carries it
        (:mod:`flexarm_deflection.payload_record`)."""
        try:
            stored = read_payload(self._model_dir)
        except ValueError as exc:
            self.get_logger().warn(f'{exc}: the configured payload {self._payload:g} kg holds')
            return
        if stored is None or stored == self._payload:
            return
        self.get_logger().info(
            f'payload {stored:g} kg, as last declared ({payload_path(self._model_dir)}; '
            f'configured {self._payload:g} kg): `flexarm payload KG` declares another')
        self._payload = stored
        self.set_parameters([Parameter('payload', value=stored)])

    def dataset_path(self, name: str) -> Path:
        return self._data_dir / f'{name or self._default_dataset}.jsonl'

    # --- collection -------------------------------------------------------------------------
    def _sender(self, action: str) -> str:
        """Who may have sent a goal of ``action`` ("goal sent by /node"; several: one of)."""
        return sender_at_acceptance(send_goal_writers(self, topics.absolute(
            action, self.get_namespace())), None, ProcTable()).text()

    def _busy(self) -> str:
        return (f'the arm is busy: {self.get_fully_qualified_name()} is '
                f'{self._progress or "starting a collection or refresh"}; nothing moved')

    def _goal_error(self, goal: Goal) -> str | None:
        if not 1 <= goal.count <= self._max_count:
            return f'count must be 1..{self._max_count}, got {goal.count}'
        if (goal.region or self._default_region) not in self._regions:
            return f'unknown region "{goal.region}"; known: {", ".join(self._regions)}'
        if (goal.strategy or self._default_strategy) not in STRATEGIES:
            return f'unknown strategy "{goal.strategy}"; known: {", ".join(STRATEGIES)}'
        return dataset_name_error(goal.dataset)

    def _collect(self, handle: ServerGoalHandle) -> Result:
        goal: Goal = handle.request
        result = Result(dataset_path=str(self.dataset_path(goal.dataset)))
        if not self._collecting.acquire(blocking=False):   # this learner's other motion runs
            result.error_code, result.error_string = Result.ARM_BUSY, self._busy()
        else:
            try:
                with self._arm.attached(), ExitStack() as arm:
                    self._run_collection(handle, goal, result, arm)
            except ArmBusy as exc:
                result.error_code, result.error_string = Result.ARM_BUSY, str(exc)
            except Exception as exc:   # last resort: a reason for the client, never a crash
                self.get_logger().error(f'collection failed: {traceback.format_exc()}')
                result.error_code = Result.FAILED
                result.error_string = f'collection failed: {type(exc).__name__}: {exc}'
            finally:
                self._progress = ''
                self._collecting.release()
        finish_goal(handle, result.error_code, Result.CANCELED)
        self.get_logger().info(f'collection ended ({result.error_code}): {result.collected} '
                               f'collected, {result.skipped} skipped, {result.total} in '
                               f'{result.dataset_path} {result.error_string}')
        return result

    def _run_collection(self, handle: ServerGoalHandle, goal: Goal, result: Result,
                        arm: ExitStack) -> None:
        """Collect into ``result`` (counts, error code and reason), the arm claimed in ``arm``
        once the goal is valid (:class:`ArmBusy` if another motion holds it)."""
        path = self.dataset_path(goal.dataset)
        reason = self._goal_error(goal)
        if reason is None and not self._arm.wait_for_joints(5.0):
            reason = 'no /joint_states from the controller'
        if reason is None:
            try:
                result.total = len(load_dataset(path)) if path.exists() else 0
            except ValueError as exc:   # not a dataset (damaged or foreign header)
                reason = str(exc)
        if reason is not None:
            result.error_code, result.error_string = Result.INVALID_GOAL, reason
            return
        region = self._regions[goal.region or self._default_region].grown(self._coverage)
        strategy = goal.strategy or self._default_strategy
        motion = arm.enter_context(self._arm.claim.claimed(
            'collect', f'{goal.count} samples ({strategy}) in region '
            f'{goal.region or self._default_region} into {path.stem}',
            self._sender(topics.COLLECT_SAMPLES)))
        taken: list[Sample] = []
        plan = self._plan(region, goal.count, strategy, goal.seed, taken)
        self.get_logger().info(f'collecting {goal.count} samples ({strategy}) in region '
                               f'{region.describe()} (grown by the coverage margin)'
                               f' into {path}')
        cancel = lambda: handle.is_cancel_requested or not self._arm.claim.holds()  # noqa: E731

        def progress(k: int, counts: Collected, sample: Sample | None) -> None:
            self._progress = f'collecting {k} of {goal.count} into {path.stem}'
            self._dataset = (path.stem, result.total + counts.collected)
            msg = self._sample_msg(sample) if sample is not None else DeflectionSample()
            if sample is not None:
                self._sample_pub.publish(msg)
            handle.publish_feedback(Feedback(k=k, n=goal.count, skipped=counts.skipped,
                                             last_sample=msg))

        self._progress = f'collecting 0 of {goal.count} into {path.stem}'
        with DatasetWriter(path) as writer:     # each sample on disk before the next move
            def store(sample: Sample) -> None:
                writer.append(sample)
                taken.append(sample)

            counts = self._collector.collect(plan, self._payload, store, cancel, progress,
                                             motion, lambda: self._arm.claim.lost)
        result.collected, result.skipped = counts.collected, counts.skipped
        result.total += counts.collected
        if self._arm.claim.lost:
            result.error_code, result.error_string = Result.CANCELED, self._arm.claim.lost
        elif counts.canceled:
            result.error_code, result.error_string = Result.CANCELED, 'canceled'
        elif counts.stopped:
            result.error_code, result.error_string = Result.FAILED, counts.stopped
        elif counts.collected == 0:
            result.error_code, result.error_string = Result.FAILED, 'no valid measurement'

    def _plan(self, region: Region, count: int, strategy: str, seed: int,
              taken: list[Sample]) -> Iterable[np.ndarray]:
        """Joints of the learning poses: space-filling in travel order, or ``active``: each
        chosen from the samples ``taken`` so far, in the training worker while the arm moves."""
        start = self._arm.positions()
        if strategy == 'active':
            self._choose(int)   # starts the worker (seconds) during the first, fixed poses
            return ActivePoses(
                self._geometry, region, count, seed,
                lambda: (np.array([s.joints for s in taken]).reshape(-1, 4),
                         np.array([s.deflection for s in taken]).reshape(-1, 3)),
                start, self._choose)
        _, plan = sample_poses(self._geometry, region, count, strategy, seed)
        return plan[travel_order(plan, start, self._geometry.velocity)]

    def _choose(self, job: Callable[..., int], *args: object) -> Future[int]:
        return self._chooser.submit(self._trainer.run, job, *args, timeout=CHOICE_TIMEOUT)

    # --- refresh ----------------------------------------------------------------------------
    def _refresh(self, handle: ServerGoalHandle) -> RefreshModel.Result:
        result = RefreshModel.Result()
        if not self._collecting.acquire(blocking=False):   # this learner's other motion runs
            result.error_code = RefreshModel.Result.ARM_BUSY
            result.error_string = self._busy()
        else:
            try:
                with self._arm.attached(), ExitStack() as arm:
                    self._run_refresh(handle, handle.request, result, arm)
            except ArmBusy as exc:
                result.error_code = RefreshModel.Result.ARM_BUSY
                result.error_string = str(exc)
            except Exception as exc:   # last resort: a reason for the client, never a crash
                self.get_logger().error(f'refresh failed: {traceback.format_exc()}')
                result.error_code = RefreshModel.Result.FAILED
                result.error_string = f'refresh failed: {type(exc).__name__}: {exc}'
            finally:
                self._progress = ''
                self._collecting.release()
        finish_goal(handle, result.error_code, RefreshModel.Result.CANCELED)
        self.get_logger().info(f'refresh ended ({result.error_code}): {result.collected} '
                               f'samples, model {result.model.version or "unchanged"} '
                               f'{result.error_string}')
        return result

    def _refresh_plan(self, goal: RefreshModel.Goal) -> tuple[np.ndarray, str]:
        """Joints to measure and the regions they cover; ValueError if nothing to refresh."""
        health = self._health
        names = refresh_regions(goal.region, goal.force, health.regions if health else [],
                                self._regions, health.stale_residual if health else 0.0)
        worst = {r.name: np.asarray(r.worst_joints).reshape(-1, 4)
                 for r in (health.regions if health else [])}
        count = goal.count or self._refresh_samples
        share = [count // len(names) + (i < count % len(names)) for i in range(len(names))]
        plan = np.concatenate([refresh_poses(
            self._geometry, self._regions[name].grown(self._coverage),
            worst.get(name, np.empty((0, 4))), n, seed=next_version(self._model_dir))
            for name, n in zip(names, share) if n])
        return plan[travel_order(plan, self._arm.positions(), self._geometry.velocity)], \
            ', '.join(names)

    def _run_refresh(self, handle: ServerGoalHandle, goal: RefreshModel.Goal,
                     result: RefreshModel.Result, arm: ExitStack) -> None:
        codes = RefreshModel.Result
        try:
            current = read_current(self._model_dir)
            if current is None:
                raise ValueError('no current model to refresh: collect samples and train')
            if not self._arm.wait_for_joints(5.0):
                raise ValueError('no /joint_states from the controller')
            predictor = load_model(current['path'])
            plan, regions = self._refresh_plan(goal)
        except (DamagedRecord, ValueError, OSError) as exc:
            result.error_code, result.error_string = codes.INVALID_GOAL, str(exc)
            return
        origin = predictor.metadata.get('provenance') or {}
        retrain = needs_retraining(origin.get('payloads', []), self._payload)
        dataset = (origin.get('dataset') or self._default_dataset) + ('' if retrain
                                                                       else '-refresh')
        path = self.dataset_path(dataset)
        result.dataset_path = str(path)
        self.get_logger().info(f'refreshing model v{current["version"]} with {len(plan)} '
                               f'samples in region {regions} into {path}')
        motion = arm.enter_context(self._arm.claim.claimed(
            'refresh', f'{len(plan)} samples in region {regions} to refresh model '
            f'v{current["version"]}', self._sender(topics.REFRESH_MODEL)))
        samples: list[Sample] = []

        def store(sample: Sample) -> None:
            writer.append(sample)
            samples.append(sample)
            self._sample_pub.publish(self._sample_msg(sample))

        def progress(k: int, counts: Collected, sample: Sample | None) -> None:
            self._progress = f'refreshing {k} of {len(plan)} into {path.stem}'
            handle.publish_feedback(RefreshModel.Feedback(k=k, n=len(plan)))

        with DatasetWriter(path) as writer:
            counts = self._collector.collect(
                plan, self._payload, store,
                lambda: handle.is_cancel_requested or not self._arm.claim.holds(), progress,
                motion, lambda: self._arm.claim.lost)
        result.collected = counts.collected
        if counts.canceled or counts.stopped or not samples:
            lost = self._arm.claim.lost
            result.error_code = codes.CANCELED if counts.canceled or lost else codes.FAILED
            result.error_string = (f'{lost}; the model is unchanged' if lost else
                                   'canceled; the model is unchanged' if counts.canceled else
                                   counts.stopped or 'no valid measurement')
            return
        if retrain:
            self._retrain(predictor, path, samples, result)
            return
        version = next_version(self._model_dir)
        mended = refreshed(predictor, self._geometry, np.array([s.joints for s in samples]),
                           np.array([s.deflection for s in samples]),
                           np.array([s.payload for s in samples]), str(version))
        mended.metadata |= {'refresh_of': str(current['version']), 'refresh_dataset': dataset}
        model_path = self._model_dir / f'{dataset}-{predictor.kind}-v{version}.model'
        mended.save(model_path)
        info = self._model_info(str(version), model_path)
        write_current(self._model_dir, version, info.kind, info.path, info.dataset_hash)
        self._announce(info)
        correction = mended.corrections[-1]
        result.model = info
        result.residual_before = correction.residual_before
        result.residual_after = correction.residual_after
        self.get_logger().info(
            f'model v{version} (v{current["version"]} refreshed with {len(samples)} samples) '
            f'announced; median residual {correction.residual_before * 1e3:.3f} mm -> '
            f'{correction.residual_after * 1e3:.3f} mm')

    def _retrain(self, predictor: Predictor, path: Path, samples: list[Sample],
                 result: RefreshModel.Result) -> None:
        """A refresh at a payload the model was not trained at: its samples went into the
        model's own dataset, which is trained again (the learner's default training of the
        model's kind, with the payload as an input: :func:`train_and_save`) — a correction
        at one payload cannot tell the arm's masses from its compliance, samples at two
        can (:mod:`flexarm_deflection.payload_bounds`)."""
        joints = np.array([s.joints for s in samples])
        deflections = np.array([s.deflection for s in samples])
        before = predictor.predict(joints, self._payload if predictor.carries_payload else None)
        version = next_version(self._model_dir)
        model_path = self._model_dir / f'{path.stem}-{predictor.kind}-v{version}.model'
        self._training = True
        try:
            metrics, samples_hash, _ = self._trainer.run(
                train_and_save, predictor.kind, {}, str(path), self._folds, str(model_path),
                self._geometry, self._screening, self._arm_id, timeout=self._train_timeout)
        except (ValueError, RuntimeError, OSError, TimeoutError) as exc:
            result.error_code = RefreshModel.Result.FAILED
            result.error_string = (f'training on {path.stem} at {self._payload:g} kg failed: '
                                   f'{exc}; the model is unchanged')
            return
        finally:
            self._training = False
        info = self._model_info(str(version), model_path)
        write_current(self._model_dir, version, info.kind, info.path, samples_hash)
        self._announce(info)
        after = load_model(model_path).predict(joints, self._payload)
        result.model = info
        result.residual_before, result.residual_after = (
            float(np.median(np.hypot(*(predicted - deflections)[:, :2].T)))
            for predicted in (before, after))
        self.get_logger().info(
            f'model v{version} announced: {path.stem} trained again with {len(samples)} '
            f'samples at {self._payload:g} kg ({metrics.samples} in all)')

    @staticmethod
    def _sample_msg(sample: Sample) -> DeflectionSample:
        sec = int(sample.stamp)
        return DeflectionSample(
            stamp=TimeMsg(sec=sec, nanosec=int((sample.stamp - sec) * 1e9)),
            joint_positions=[float(v) for v in sample.joints], payload=float(sample.payload),
            rigid_pose=planar(sample.rigid_pose), measured_pose=planar(sample.measured_pose),
            deflection=planar(sample.deflection), holes_used=int(sample.holes_used),
            residual=float(sample.residual), motion=sample.motion)

    # --- training ---------------------------------------------------------------------------
    def _train(self, request: Train.Request, response: Train.Response) -> Train.Response:
        kind = request.kind or self._default_kind
        try:
            reason = dataset_name_error(request.dataset)
            if reason is not None:
                raise ValueError(reason)
            if self._collecting.locked():
                raise RuntimeError('busy: a collection is running; train when it has ended')
            path = self.dataset_path(request.dataset)
            version = next_version(self._model_dir)
            model_path = self._model_dir / (
                f'{request.dataset or self._default_dataset}-{kind}-v{version}.model')
            settings = json.loads(request.settings_json) if request.settings_json else {}
            if not isinstance(settings, dict):
                raise ValueError('settings_json must be a JSON object')
            make_model(kind, settings)      # unknown kind or bad settings: fail here
            if not path.exists():
                raise ValueError(f'no dataset at {path}: collect samples first')
            self._training = True
            try:
                metrics, samples_hash, skipped = self._trainer.run(
                    train_and_save, kind, settings, str(path), self._folds, str(model_path),
                    self._geometry, self._screening, self._arm_id, timeout=self._train_timeout)
            finally:
                self._training = False
            info = self._model_info(str(version), model_path)
            write_current(self._model_dir, version, kind, info.path, samples_hash)
        except (ValueError, RuntimeError, OSError, TimeoutError) as exc:
            return self._train_failed(response, str(exc))
        except Exception as exc:   # last resort: a reason for the caller, never a crash
            self.get_logger().error(traceback.format_exc())
            return self._train_failed(response, f'{type(exc).__name__}: {exc}')
        self._announce(info)
        self._trained = (True, f'model v{version}: {kind}, {metrics.samples} samples')
        response.success, response.model_version = True, info.version
        if skipped:
            response.message = (f'{len(skipped)} damaged record(s) of {path} skipped (lines '
                                f'{", ".join(map(str, skipped))})')
            self.get_logger().warn(response.message)
        response.model_path, response.metrics = info.path, info.metrics
        self.get_logger().info(
            f'model v{version} ({kind} {metrics.selected_settings}, {metrics.samples} samples) '
            f'announced; validation max |error| x {metrics.max_error_x * 1e3:.3f} mm, '
            f'y {metrics.max_error_y * 1e3:.3f} mm; max slope {metrics.max_slope:.3f}')
        if metrics.excluded_samples:
            self.get_logger().warn(
                f'{len(metrics.excluded_samples)} outlier sample(s) excluded from training: '
                f'indices {list(metrics.excluded_samples)} of {path}')
        return response

    def _train_failed(self, response: Train.Response, reason: str) -> Train.Response:
        response.success, response.message = False, f'training failed: {reason}'
        self._trained = (False, response.message)
        self.get_logger().error(response.message + '; the previous model stays active')
        return response

    def destroy_node(self) -> None:
        self._trainer.shutdown()   # first: the threads that wait on a training end with it
        self._chooser.shutdown(wait=False, cancel_futures=True)
        self._goals.shutdown()
        self._models.shutdown()
        self._collect_server.destroy()   # Node.destroy_node leaves actions (and the node) alive
        self._refresh_server.destroy()
        super().destroy_node()

    def _model_info(self, version: str, path: Path) -> ModelInfo:
        """The announcement of a model file: provenance, metrics and whether it was made for
        this arm. ValueError/OSError if it cannot be loaded (unreadable, damaged)."""
        predictor = load_model(path)
        meta = predictor.metadata
        origin = meta.get('provenance') or {}
        info = ModelInfo(stamp=self.get_clock().now().to_msg(), version=version,
                         kind=predictor.kind, path=str(path),
                         dataset_hash=str(meta.get('dataset_hash', '')),
                         dataset=str(origin.get('dataset', '')),
                         payloads=[float(p) for p in origin.get('payloads', [])],
                         warning=fit_warning(meta, self._arm_id))
        if meta.get('metrics'):
            info.metrics = PredictionMetrics(**meta['metrics'])
        if info.warning:
            self.get_logger().warn(f'model v{version}: {info.warning}')
        return info

    def _announce(self, info: ModelInfo) -> None:
        """Publish ``info`` on /learner/model (latched): the current model from now on."""
        self._model_pub.publish(info)
        self._announced, self._announce_error = info, ''

    def _use_model(self, request: UseModel.Request,
                   response: UseModel.Response) -> UseModel.Response:
        try:
            path = find_model(self._model_dir, request.version)
            info = self._model_info(str(int(request.version)), path)
            write_current(self._model_dir, int(info.version), info.kind, info.path,
                          info.dataset_hash)
        except (ValueError, OSError) as exc:
            response.success, response.message = False, f'model not changed: {exc}'
            self.get_logger().error(response.message)
            return response
        self._announce(info)
        self.get_logger().info(f'model v{info.version} made current on request and announced')
        response.success, response.model = True, info
        return response

    def _announce_current(self) -> None:
        """Announce the model ``current.json`` names; if it cannot be, say why (the ``model``
        status turns ERROR: ``flexarm status`` and ``flexarm up`` show it)."""
        try:
            current = read_current(self._model_dir)
            if current is None:
                return
            info = self._model_info(current['version'], Path(current['path']))
        except DamagedRecord as exc:
            self._announce_error = str(exc)
        except (ValueError, OSError) as exc:        # the model file it names
            self._announce_error = unloadable_text(self._model_dir, current, str(exc))
        if self._announce_error:
            self.get_logger().error(f'no model announced: {self._announce_error}')
            return
        self._announce(info)
        self.get_logger().info(f'announced the current model v{info.version} ({info.kind}, '
                               f'dataset {info.dataset or "unknown"})')

def main(args: list[str] | None = None) -> None:
    run(LearnerNode, args)


if __name__ == '__main__':
    main()
