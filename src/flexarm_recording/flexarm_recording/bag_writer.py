"""Write rosbag2-compatible MCAP bags from raw CDR messages (no rclpy).

A bag is a directory ``<dir>/`` holding ``<dir.name>.mcap`` and ``metadata.yaml``, as
``ros2 bag record -s mcap`` makes it: profile ``ros2``, one ``ros2msg`` schema per type with
its full text (:mod:`flexarm_recording.bag_schema`), one ``cdr`` channel per topic with the
``offered_qos_profiles`` (a YAML string) and ``topic_type_hash`` metadata, and on close the
``rosbag2`` metadata record whose ``serialized_metadata`` is the bag metadata (version 9,
Jazzy), the same mapping that ``metadata.yaml`` holds under ``rosbag2_bagfile_information``.
From version 9 on, rosbag2 reads a topic's ``offered_qos_profiles`` there as a YAML list of
profiles, not as the string the channel carries.

Messages are grouped in chunks, each compressed (``compression``: ``zstd`` by default, as
rosbag2's MCAP writer does, ``lz4`` or ``none``) inside the MCAP file, so every MCAP
reader (``mcap``, ``mcap-ros2-support``, rosbags, rosbag2, Foxglove) decodes it and the rosbag2
metadata names no file compression. Measured on this machine (4-joint JointState, 156 bytes,
50 000 of them): writing costs 4.3 us a message uncompressed, 4.3 with lz4 and 4.7 with zstd,
and the file is 6x (lz4) or 9x (zstd) smaller; a recorded demo's bag 4x (zstd). A chunk is
written when it reaches ``chunk_size`` (before compression) or on :meth:`BagWriter.flush`;
every written chunk stays readable if the process dies (SIGKILL), and each flush also rewrites
``metadata.yaml`` (atomically) so the directory describes what is on disk.
"""
from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mcap
import yaml
from mcap.writer import CompressionType, Writer

from flexarm_recording.bag_schema import message_definition

METADATA_VERSION = 9            # rosbag2 bag metadata version of ROS 2 Jazzy
ROS_DISTRO = 'jazzy'
LIBRARY = f'flexarm_recording.bag_writer (mcap {mcap.__version__})'
DEFAULT_CHUNK_SIZE = 512 * 1024
COMPRESSIONS = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE}
DEFAULT_COMPRESSION = 'zstd'


def offered_qos_yaml(profiles: Sequence[Mapping[str, Any]]) -> str:
    """rosbag2's ``offered_qos_profiles`` string: a YAML list of QoS profile mappings.

    Each profile has ``history``, ``depth``, ``reliability``, ``durability``, ``deadline``,
    ``lifespan``, ``liveliness``, ``liveliness_lease_duration`` and
    ``avoid_ros_namespace_conventions``; policies are rmw names (``keep_last``,
    ``reliable``, ``transient_local``, ``automatic``), durations ``{sec, nsec}``.
    """
    if not profiles:
        return ''
    return yaml.safe_dump([dict(p) for p in profiles], default_flow_style=False,
                          sort_keys=False)


def duration_yaml(nanoseconds: int) -> dict[str, int]:
    """A duration as rosbag2 writes it in QoS profiles: ``{sec, nsec}``."""
    return {'sec': nanoseconds // 1_000_000_000, 'nsec': nanoseconds % 1_000_000_000}


@dataclass
class _Topic:
    name: str
    type: str
    channel_id: int
    offered_qos_profiles: list[dict[str, Any]]
    type_hash: str
    message_count: int = 0


class BagWriter:
    """One MCAP bag being written; create, ``add_topic``, ``write``, ``flush``, ``close``.

    Not thread-safe: call it from one thread (the recorder's executor).
    """

    def __init__(self, bag_dir: str | Path, chunk_size: int = DEFAULT_CHUNK_SIZE,
                 compression: str = DEFAULT_COMPRESSION) -> None:
        """Create ``bag_dir`` (it must not exist or be empty) and start its MCAP file, its
        chunks compressed with ``compression`` (:data:`COMPRESSIONS`)."""
        if compression not in COMPRESSIONS:
            raise ValueError(f'chunk compression {compression!r}: one of '
                             f'{", ".join(COMPRESSIONS)}')
        self.bag_dir = Path(bag_dir)
        if self.bag_dir.exists() and any(self.bag_dir.iterdir()):
            raise FileExistsError(f'bag directory {self.bag_dir} exists and is not empty')
        self.bag_dir.mkdir(parents=True, exist_ok=True)
        self.path = self.bag_dir / f'{self.bag_dir.name}.mcap'
        self._file = open(self.path, 'wb')
        self._writer = Writer(self._file, chunk_size=chunk_size,
                              compression=COMPRESSIONS[compression])
        self._writer.start(profile='ros2', library=LIBRARY)
        self._schemas: dict[str, int] = {}
        self._topics: dict[str, _Topic] = {}
        self._start_ns: int | None = None
        self._end_ns = 0
        self.closed = False
        self._write_metadata_yaml()

    @property
    def message_count(self) -> int:
        return sum(t.message_count for t in self._topics.values())

    def add_topic(self, topic: str, type_name: str,
                  qos_profiles: Sequence[Mapping[str, Any]] = (), type_hash: str = '') -> None:
        """Register a topic of type ``pkg/msg/Type`` with its publishers' offered QoS."""
        if topic in self._topics:
            raise ValueError(f'topic {topic} already added')
        schema_id = self._schemas.get(type_name)
        if schema_id is None:
            schema_id = self._writer.register_schema(
                type_name, 'ros2msg', message_definition(type_name).encode())
            self._schemas[type_name] = schema_id
        qos = [dict(p) for p in qos_profiles]
        channel_metadata = {'offered_qos_profiles': offered_qos_yaml(qos)}
        if type_hash:
            channel_metadata['topic_type_hash'] = type_hash
        channel_id = self._writer.register_channel(topic, 'cdr', schema_id, channel_metadata)
        self._topics[topic] = _Topic(topic, type_name, channel_id, qos, type_hash)

    def write(self, topic: str, data: bytes, log_time_ns: int,
              publish_time_ns: int | None = None) -> None:
        """Append one serialized (CDR) message of an added topic."""
        entry = self._topics[topic]
        self._writer.add_message(entry.channel_id, log_time_ns, data,
                                 log_time_ns if publish_time_ns is None else publish_time_ns,
                                 sequence=entry.message_count)
        entry.message_count += 1
        self._start_ns = log_time_ns if self._start_ns is None else min(self._start_ns,
                                                                       log_time_ns)
        self._end_ns = max(self._end_ns, log_time_ns)

    def flush(self) -> None:
        """Write the chunk in progress and the buffers to the file; update metadata.yaml."""
        self._writer.flush()
        self._write_metadata_yaml()

    def close(self) -> None:
        """Write the ``rosbag2`` metadata record and the summary; close; final metadata.yaml."""
        if self.closed:
            return
        self._writer.flush()
        self._writer.add_metadata(
            'rosbag2', {'serialized_metadata': yaml.safe_dump(self.metadata(),
                                                              sort_keys=False)})
        self._writer.finish()
        self._file.close()
        self.closed = True
        self._write_metadata_yaml()

    def metadata(self) -> dict[str, Any]:
        """rosbag2 bag metadata (version 9) of what has been written so far."""
        start = self._start_ns or 0
        duration = self._end_ns - start if self._start_ns is not None else 0
        count = self.message_count
        return {
            'version': METADATA_VERSION,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': count,
            'topics_with_message_count': [
                {'topic_metadata': {'name': t.name, 'type': t.type,
                                    'serialization_format': 'cdr',
                                    'offered_qos_profiles': t.offered_qos_profiles,
                                    'type_description_hash': t.type_hash},
                 'message_count': t.message_count}
                for t in self._topics.values()],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [self.path.name],
            'files': [{'path': self.path.name,
                       'starting_time': {'nanoseconds_since_epoch': start},
                       'duration': {'nanoseconds': duration},
                       'message_count': count}],
            'custom_data': {},
            'ros_distro': ROS_DISTRO,
        }

    def _write_metadata_yaml(self) -> None:
        text = yaml.safe_dump({'rosbag2_bagfile_information': self.metadata()},
                              sort_keys=False)
        fd, tmp = tempfile.mkstemp(dir=self.bag_dir, prefix='.metadata.', suffix='.yaml')
        try:
            os.fchmod(fd, 0o644)
            with os.fdopen(fd, 'w', encoding='utf-8') as f:
                f.write(text)
            os.replace(tmp, self.bag_dir / 'metadata.yaml')
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
