"""``flexarm_scene``: the working regions, the learning samples and the predicted deflection
field as ``visualization_msgs/MarkerArray`` on ``/scene/markers`` (latched), in ``base_link``.

Consumes ``/learner/samples``, the compensator's model on ``/compensator/active_model`` and
``/payload``; builds the array only while ``/scene/markers`` has a subscriber. The field is
:mod:`flexarm_deflection.deflection_field` (the model run at the payload:
:mod:`flexarm_deflection.at_payload`), the markers' geometry
:mod:`flexarm_description.scene`.

Explained in docs/nodes.md#the-scene-flexarm_scene.
"""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Point, Vector3
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile
from std_msgs.msg import ColorRGBA, Float64, Header
from visualization_msgs.msg import Marker, MarkerArray

from flexarm_core import topics
from flexarm_core.health_report import OK, WARN, Status, status
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.regions import regions_from_dict
from flexarm_core.ros.diagnostics import DiagnosticsPublisher
from flexarm_core.ros.node_main import run
from flexarm_core.ros.node_params import declare, declare_tree
from flexarm_core.ros.stamps import GraphTime
from flexarm_deflection.deflection_field import deflection_field
from flexarm_description.chain import BASE_FRAME
from flexarm_description.scene import (
    deflection_arrows,
    region_label,
    region_outline,
    sample_points,
)
from flexarm_msgs.msg import DeflectionSample, ModelInfo

REGION_COLOUR = ColorRGBA(r=0.3, g=0.8, b=0.3, a=1.0)
SAMPLE_COLOUR = ColorRGBA(r=0.2, g=0.5, b=1.0, a=0.9)
ARROW_COLOUR = ColorRGBA(r=1.0, g=0.3, b=0.2, a=1.0)


def _point(p: np.ndarray) -> Point:
    return Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def _marker(header: Header, ns: str, marker_id: int, kind: int, colour: ColorRGBA,
            scale: Vector3, points: list[Point] | None = None) -> Marker:
    marker = Marker(header=header, ns=ns, id=marker_id,
                    type=kind, action=Marker.ADD, color=colour, scale=scale,
                    points=points or [])
    marker.pose.orientation.w = 1.0
    return marker


class SceneNode(Node):
    def __init__(self) -> None:
        super().__init__('flexarm_scene')
        self._geometry = ArmGeometry.from_dict(declare_tree(self, 'arm', 'config/arm.yaml'))
        regions = regions_from_dict(declare_tree(self, 'regions', 'config/learner.yaml'))
        shown = declare(self, 'regions_shown', 'config/description.yaml')
        unknown = [name for name in shown if name not in regions]
        if unknown:
            raise ValueError(f'regions_shown names unknown regions {unknown}')
        self._regions = [regions[name] for name in shown]
        self._scale = declare(self, 'arrow_scale', 'config/description.yaml')
        self._count = declare(self, 'field_points', 'config/description.yaml')
        self._max_samples = declare(self, 'max_samples', 'config/description.yaml')
        self._samples: list[tuple[float, float, float]] = []
        self._model: ModelInfo | None = None
        self._payload = 0.0
        self._arrows: list[tuple[np.ndarray, np.ndarray]] = []
        self._changed = True
        self._field_stale = False       # model or payload changed since the field was made
        self._watched = False           # /scene/markers has a subscriber
        self._field_problem = ''
        self._graph_time = GraphTime(self)
        latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
        self._pub = self.create_publisher(
            MarkerArray, topics.SCENE_MARKERS, latched,
            event_callbacks=PublisherEventCallbacks(matched=self._on_matched))
        self.create_subscription(DeflectionSample, topics.SAMPLES, self._on_sample, 100)
        self.create_subscription(ModelInfo, topics.ACTIVE_MODEL, self._on_model, latched)
        self.create_subscription(Float64, topics.PAYLOAD, self._on_payload, latched)
        self.create_timer(1.0, self._publish, clock=Clock(clock_type=ClockType.STEADY_TIME))
        DiagnosticsPublisher(self, self._statuses, stamp=self._graph_time.stamp)

    def _on_sample(self, msg: DeflectionSample) -> None:
        pose = msg.measured_pose
        self._samples = (self._samples + [(pose.x, pose.y, pose.phi)])[-self._max_samples:]
        self._changed = True

    def _on_matched(self, info) -> None:
        watched = info.current_count > 0
        self._changed |= watched and not self._watched      # a newcomer: publish again
        self._watched = watched

    def _on_model(self, msg: ModelInfo) -> None:
        self._model = msg
        self._field_stale = self._changed = True

    def _on_payload(self, msg: Float64) -> None:
        self._payload = float(msg.data)
        self._field_stale = self._changed = True

    def _update_field(self) -> None:
        self._arrows, self._field_stale, self._field_problem = [], False, ''
        if self._model is None or not self._model.path:
            return
        # The predictors (scipy: some 45 MB of the process) are loaded once a model is in use.
        from flexarm_deflection.at_payload import AtPayload
        from flexarm_deflection.models import load_model

        try:
            model = AtPayload(load_model(self._model.path), self._payload)
        except (OSError, ValueError) as exc:
            self._field_problem = f'model {self._model.version}: no deflection field: {exc}'
            self.get_logger().warn(self._field_problem)
            return
        for region in self._regions:
            poses, deflections = deflection_field(self._geometry, region, model.predict,
                                                  self._count)
            self._arrows += deflection_arrows(poses, deflections, self._scale)

    def _statuses(self) -> list[Status]:
        version = self._model.version if self._model is not None else ''
        values = {'model': version, 'payload [kg]': self._payload,
                  'samples': len(self._samples), 'field arrows': len(self._arrows)}
        if self._field_problem:
            return [status(self.get_name(), 'markers', WARN, self._field_problem, values)]
        field = f'field of model {version}' if version else 'no model in use yet'
        return [status(self.get_name(), 'markers', OK,
                       f'{len(self._samples)} samples, {field}', values)]

    def _publish(self) -> None:
        if not self._changed or not self._watched:
            return
        stamp = self._graph_time.stamp()
        if not (stamp.sec or stamp.nanosec):
            return
        if self._field_stale:
            self._update_field()
        self._changed = False
        header = Header(stamp=stamp, frame_id=BASE_FRAME)
        markers = [Marker(header=header, action=Marker.DELETEALL)]
        for i, region in enumerate(self._regions):
            markers.append(_marker(header, 'regions', i, Marker.LINE_STRIP, REGION_COLOUR,
                                   Vector3(x=0.004), [_point(p) for p in region_outline(region)]))
            where, text = region_label(region)
            label = _marker(header, 'region_labels', i, Marker.TEXT_VIEW_FACING, REGION_COLOUR,
                            Vector3(z=0.04))
            label.pose.position, label.text = _point(where), text
            markers.append(label)
        if self._samples:
            markers.append(_marker(header, 'samples', 0, Marker.SPHERE_LIST, SAMPLE_COLOUR,
                                   Vector3(x=0.012, y=0.012, z=0.012),
                                   [_point(p) for p in sample_points(np.array(self._samples))]))
        for i, (start, end) in enumerate(self._arrows):
            markers.append(_marker(header, 'deflection', i, Marker.ARROW, ARROW_COLOUR,
                                   Vector3(x=0.004, y=0.01, z=0.015),
                                   [_point(start), _point(end)]))
        self._pub.publish(MarkerArray(markers=markers))


def main(args: list[str] | None = None) -> None:
    run(SceneNode, args)


if __name__ == '__main__':
    main()
