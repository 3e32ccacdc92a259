"""A stand-in for a ros2_control arm and its camera driver, for the node-level tests of the
``ros2_control`` robot entry: no simulator node, no ``/clock``, everything on wall time.

What it offers is what a controller_manager with config/controllers.yaml and a camera driver
would: ``/joint_states`` (joint_state_broadcaster, 50 Hz), ``/joint_trajectory_controller/
joint_trajectory`` (joint_trajectory_controller's topic: a new trajectory replaces the one
running, from where the reference is and how fast it goes; the empty one holds the arm where
it is) and the tip camera's ``Image`` and latched ``CameraInfo`` (5 Hz). Between the
trajectory's points the reference is the cubic through their positions and velocities
(:class:`~flexarm_core.joint_trajectory.SampledTrajectory`, the controller's spline without
accelerations); the joints follow it with the hardware's own tracking error, a first-order lag of
``TRACKING_LAG`` s. The tip is the simulated real arm's deflected pose at the joints (the
simulator's plant, config/sim.yaml), seen by an ideal camera. Run as a node process::

    python -m ros2_control_standin --ros-args ...   # with tests/ on PYTHONPATH
"""
from __future__ import annotations

import math
import time

import numpy as np
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory

from flexarm_core import topics
from flexarm_core.frames import BASE_FRAME
from flexarm_core.joint_trajectory import SampledTrajectory
from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry
from flexarm_core.node_main import run
from flexarm_core.params import load_config
from flexarm_core.trajectory_message import trajectory_from
from flexarm_sim.camera import CameraRenderer
from flexarm_sim.plant import configured_plant
from flexarm_vision.camera_info import camera_info
from flexarm_vision.camera_model import CameraModel

RATE = 50.0            # [Hz, wall] of /joint_states and the joints' update
CAMERA_EVERY = 10      # updates per camera frame: 5 Hz
TRACKING_LAG = 0.05    # [s] of the joints behind the reference
CAMERA_FRAME = 'tip_camera_optical_frame'
START = np.array([0.0, 0.6, -0.5, -0.5])


class Ros2ControlStandIn(Node):

    def __init__(self) -> None:
        super().__init__('ros2_control_standin')
        config = load_config('arm.yaml', 'camera.yaml')
        geometry = ArmGeometry.from_dict(config['arm'])
        self._plant = configured_plant(geometry)
        self._camera = CameraRenderer.from_dict(config)
        self._info = camera_info(CameraModel.from_dict(config['camera']).intrinsics,
                                 Header(frame_id=CAMERA_FRAME))
        self._rng = np.random.default_rng(5)
        self._q = START.copy()
        self._trajectory: tuple[SampledTrajectory, float] | None = None   # and when it came
        self._held = START.copy()         # the reference without a trajectory
        self._tip = self._plant.pose(self._q)
        self._ticks = 0
        self._joints = self.create_publisher(JointState, topics.JOINT_STATES, 10)
        self._images = self.create_publisher(Image, topics.CAMERA_IMAGE, 5)
        self._infos = self.create_publisher(
            CameraInfo, topics.CAMERA_INFO,
            QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL))
        self.create_subscription(JointTrajectory, topics.JOINT_TRAJECTORY, self._on_trajectory,
                                 10)
        self.create_timer(1.0 / RATE, self._update)

    def _reference_now(self) -> tuple[np.ndarray, np.ndarray]:
        if self._trajectory is None:
            return self._held, np.zeros_like(self._held)
        trajectory, since = self._trajectory
        return trajectory.at(time.monotonic() - since)

    def _on_trajectory(self, msg: JointTrajectory) -> None:
        position, velocity = self._reference_now()
        if msg.points:
            trajectory = trajectory_from(msg).starting(position, velocity)
            self._trajectory = (trajectory, time.monotonic())
        else:
            self._trajectory, self._held = None, self._q.copy()

    def _update(self) -> None:
        dt = 1.0 / RATE
        before = self._q.copy()
        self._q += (self._reference_now()[0] - self._q) * (1.0 - math.exp(-dt / TRACKING_LAG))
        stamp = self.get_clock().now().to_msg()
        self._joints.publish(JointState(
            header=Header(stamp=stamp, frame_id=BASE_FRAME), name=list(JOINT_NAMES),
            position=self._q.tolist(), velocity=((self._q - before) / dt).tolist()))
        self._ticks += 1
        if self._ticks % CAMERA_EVERY:
            return
        tip = self._plant.pose(self._q)
        speed = (tip - self._tip) / (CAMERA_EVERY * dt)
        self._tip = tip
        pixels = self._camera.render(tip, tip_velocity=speed, rng=self._rng)
        height, width = pixels.shape
        header = Header(stamp=stamp, frame_id=CAMERA_FRAME)
        self._images.publish(Image(header=header, height=height, width=width, encoding='mono8',
                                   is_bigendian=0, step=width, data=pixels.tobytes()))
        self._info.header = header
        self._infos.publish(self._info)


def main(args: list[str] | None = None) -> None:
    run(Ros2ControlStandIn, args)


if __name__ == '__main__':
    main()
