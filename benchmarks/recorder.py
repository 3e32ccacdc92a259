"""Recorder throughput: messages/s, camera MB/s and dropped messages of flexarm_recorder.

Starts the recorder as its own process (as ``flexarm up --record`` does) in a private ROS
domain, publishes from this process for ``--seconds``: /joint_states at ``--joint-rate`` Hz
and 640x480 mono8 /camera/image_raw at ``--image-rate`` Hz (reliable, keep last), waits
until the recorder has flushed what it will get, stops it with SIGINT, then reads the bag
back and compares with what was published (dropped = published - recorded). Drops depend
on the machine's load (printed): a starved recorder overflows its queues. The recorder's CPU
(``recorder_cores``: user + system time per wall second) is measured from the first message
published until the last was flushed: its start-up (imports, discovery) is left out.

    python benchmarks/recorder.py [--seconds 10] [--joint-rate 1000] [--image-rate 30]
        [--compression zstd|lz4|none] [--json]
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import rclpy
import yaml
from rclpy.context import Context
from rclpy.qos import QoSProfile
from sensor_msgs.msg import Image, JointState

from flexarm_bringup.launcher import NodeProcess, load_optional, ros_env, stop_all
from flexarm_core import topics
from flexarm_core.processes import cpu_seconds
from flexarm_recording.bag_tools import bag_info, read_messages

WIDTH, HEIGHT = 640, 480
# Full names (the root namespace): the bag names its topics so, not as topics.py's relative ones
JOINT_STATES = topics.absolute(topics.JOINT_STATES)
CAMERA_IMAGE = topics.absolute(topics.CAMERA_IMAGE)


def _flushed_count(bag_dir: Path) -> int:
    try:
        meta = yaml.safe_load((bag_dir / 'metadata.yaml').read_text())
        return meta['rosbag2_bagfile_information']['message_count']
    except (OSError, yaml.YAMLError, TypeError, KeyError):
        return 0


def publish(node: Any, seconds: float, joint_rate: float, image_rate: float,
            started: Callable[[], None] = lambda: None) -> dict[str, int]:
    """Publish both streams on schedule (catching up when late); return counts sent.
    ``started()`` is called once both are matched, just before the first message."""
    joint_pub = node.create_publisher(JointState, JOINT_STATES, QoSProfile(depth=1000))
    image_pub = node.create_publisher(Image, CAMERA_IMAGE, QoSProfile(depth=30))
    deadline = time.monotonic() + 20.0
    while min(joint_pub.get_subscription_count(), image_pub.get_subscription_count()) == 0:
        if time.monotonic() > deadline:
            raise TimeoutError('the recorder did not subscribe within 20 s')
        time.sleep(0.05)
    time.sleep(1.0)                                  # let both sides finish matching
    joint = JointState(name=['joint1', 'joint2', 'joint3', 'joint4'], position=[0.0] * 4,
                       velocity=[0.0] * 4)
    image = Image(height=HEIGHT, width=WIDTH, encoding='mono8', step=WIDTH,
                  data=bytes(range(256)) * (WIDTH * HEIGHT // 256))
    sent = {JOINT_STATES: 0, CAMERA_IMAGE: 0}
    started()
    start = time.monotonic()
    while (elapsed := time.monotonic() - start) < seconds:
        while sent[JOINT_STATES] < elapsed * joint_rate:
            joint.position[0] = float(sent[JOINT_STATES])
            joint_pub.publish(joint)
            sent[JOINT_STATES] += 1
        if sent[CAMERA_IMAGE] < elapsed * image_rate:
            image.header.frame_id = str(sent[CAMERA_IMAGE])
            image_pub.publish(image)
            sent[CAMERA_IMAGE] += 1
        time.sleep(0.0002)
    sent['publish_seconds'] = time.monotonic() - start
    return sent


def measure(seconds: float, joint_rate: float, image_rate: float, domain_id: int,
            run_dir: Path, compression: str = 'zstd') -> dict[str, Any]:
    bag_dir = run_dir / 'bench'
    recorder = NodeProcess(load_optional()['flexarm_recorder'],
                           ros_env(domain_id, run_dir / 'ros_log'), run_dir / 'recorder.log',
                           {'bag_directory': str(run_dir), 'bag_name': 'bench',
                            'record_images': True, 'compression': compression})
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = rclpy.create_node('bench_recorder', context=context)
    recorder.start()
    marks: dict[str, float] = {}

    def started() -> None:
        marks['cpu'], marks['wall'] = cpu_seconds(recorder.process.pid), time.monotonic()

    try:
        sent = publish(node, seconds, joint_rate, image_rate, started)
        total = sent[JOINT_STATES] + sent[CAMERA_IMAGE]
        deadline, last, stalled_since = time.monotonic() + 30.0, -1, time.monotonic()
        while time.monotonic() < deadline and (count := _flushed_count(bag_dir)) < total:
            if count != last:
                last, stalled_since = count, time.monotonic()
            elif time.monotonic() - stalled_since > 3.0:
                break                                # nothing more is coming
            time.sleep(0.1)
        cpu = cpu_seconds(recorder.process.pid) - marks['cpu']
        busy = time.monotonic() - marks['wall']
        recorder.signal(signal.SIGINT)
        recorder.process.wait(timeout=15.0)
    finally:
        stop_all([recorder])
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    info = bag_info(bag_dir)
    image_bytes = sum(len(m.data) for _, _, m in read_messages(bag_dir, [CAMERA_IMAGE]))
    recorded = {t: info['topics'].get(t, {}).get('count', 0)
                for t in (JOINT_STATES, CAMERA_IMAGE)}
    window = sent['publish_seconds']
    return {
        'seconds': window,
        'published': {t: sent[t] for t in recorded},
        'recorded': recorded,
        'dropped': {t: sent[t] - recorded[t] for t in recorded},
        'messages_per_s': sum(recorded.values()) / window,
        'joint_states_per_s': recorded[JOINT_STATES] / window,
        'images_per_s': recorded[CAMERA_IMAGE] / window,
        'image_mb_per_s': image_bytes / window / 1e6,
        'bag_mb': info['size_bytes'] / 1e6,
        'recorder_cores': cpu / busy, 'recorder_cpu_percent': 100.0 * cpu / busy,
        'recorder_us_per_message': 1e6 * cpu / max(1, sum(recorded.values())),
        'compression': compression,
        'clean_close': info['complete'] and info['rosbag2_metadata'],
        'load_average_1min': os.getloadavg()[0],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--joint-rate', type=float, default=1000.0)
    parser.add_argument('--image-rate', type=float, default=30.0)
    parser.add_argument('--compression', default='zstd', choices=('zstd', 'lz4', 'none'))
    parser.add_argument('--domain-id', type=int, default=92)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        r = measure(args.seconds, args.joint_rate, args.image_rate, args.domain_id, Path(tmp),
                    args.compression)
    print(f'published for {r["seconds"]:.1f} s; recorder CPU {r["recorder_cpu_percent"]:.0f} %'
          f' ({r["recorder_us_per_message"]:.0f} us a message), bag {r["bag_mb"]:.1f} MB '
          f'({r["compression"]}), closed cleanly: {r["clean_close"]}, '
          f'machine load {r["load_average_1min"]:.1f}')
    print('topic                published  recorded  dropped')
    for t in r['published']:
        print(f'{t:<20} {r["published"][t]:9d} {r["recorded"][t]:9d} {r["dropped"][t]:8d}')
    print(f'recorded {r["messages_per_s"]:.0f} messages/s ({r["joint_states_per_s"]:.0f} joint '
          f'states/s, {r["images_per_s"]:.1f} images/s = {r["image_mb_per_s"]:.2f} MB/s)')
    if args.json:
        print(json.dumps(r))


if __name__ == '__main__':
    main()
