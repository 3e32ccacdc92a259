"""A stand-in for a ros2_control arm and its camera driver, for the node-level tests of the
``ros2_control`` robot entry: no simulator node, no ``/clock``, everything on wall time.

What it offers is what a controller_manager with config/controllers.yaml and a camera driver
would: ``/joint_states`` (joint_state_broadcaster, 50 Hz), ``/joint_trajectory_controller/
joint_trajectory`` (joint_trajectory_controller's topic: a new trajectory replaces the one
running, starting from where the reference is; the empty one holds the arm where it is) and
the tip camera's ``Image`` and latched ``CameraInfo`` (5 Hz). Between the trajectory's points
the reference is the cubic through their positions and velocities, as the controller's
spline; the joints follow it with the hardware's own tracking error, a first-order lag of
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
from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry
from flexarm_core.node_main import run
from flexarm_core.params import load_config
from flexarm_sim.camera import CameraRenderer
from flexarm_sim.plant import configured_plant
from flexarm_vision.camera_info import camera_info
from flexarm_vision.camera_model import CameraModel

RATE = 50.0            # [Hz, wall] of /joint_states and the joints' update
CAMERA_EVERY = 10      # updates per camera frame: 5 Hz
TRACKING_LAG = 0.05    # [s] of the joints behind the reference
CAMERA_FRAME = 'tip_camera_optical_frame'
START = np.array([0.0, 0.6, -0.5, -0.5])


def hermite(t: float, t0: float, t1: float, p0: np.ndarray, v0: np.ndarray, p1: np.ndarray,
            v1: np.ndarray) -> np.ndarray:
    """The cubic from (p0, v0) at ``t0`` to (p1, v1) at ``t1``, at ``t``."""
    h = t1 - t0
    s = min(max((t - t0) / h, 0.0), 1.0) if h > 0 else 1.0
    return ((2 * s ** 3 - 3 * s ** 2 + 1) * p0 + (s ** 3 - 2 * s ** 2 + s) * h * v0
            + (-2 * s ** 3 + 3 * s ** 2) * p1 + (s ** 3 - s ** 2) * h * v1)


class Trajectory:
    """A received trajectory, from the reference where it was when it came."""

    def __init__(self, msg: JointTrajectory, received: float, start: np.ndarray) -> None:
        order = [list(msg.joint_names).index(n) for n in JOINT_NAMES]
        self.received = received
        self.times = [0.0] + [p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
                              for p in msg.points]
        zero = np.zeros(len(JOINT_NAMES))
        self.positions = [start] + [np.asarray(p.positions)[order] for p in msg.points]
        self.velocities = [zero] + [np.asarray(p.velocities)[order] if len(p.velocities)
                                    else zero for p in msg.points]

    def at(self, now: float) -> np.ndarray:
        t = now - self.received
        i = next((k for k, end in enumerate(self.times) if end >= t), len(self.times) - 1)
        if i == 0:
            return self.positions[0]
        return hermite(t, self.times[i - 1], self.times[i], self.positions[i - 1],
                       self.velocities[i - 1], self.positions[i], self.velocities[i])


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
        self._reference: np.ndarray | Trajectory = START.copy()
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

    def _reference_now(self) -> np.ndarray:
        ref = self._reference
        return ref.at(time.monotonic()) if isinstance(ref, Trajectory) else ref

    def _on_trajectory(self, msg: JointTrajectory) -> None:
        here = self._reference_now()
        self._reference = (Trajectory(msg, time.monotonic(), here) if msg.points
                           else self._q.copy())

    def _update(self) -> None:
        dt = 1.0 / RATE
        before = self._q.copy()
        self._q += (self._reference_now() - self._q) * (1.0 - math.exp(-dt / TRACKING_LAG))
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
