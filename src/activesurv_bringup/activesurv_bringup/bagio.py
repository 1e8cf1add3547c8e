"""rosbag2 I/O with the ``rosbags`` library: MCAP bags with our message definitions inside.

``ros2 bag`` and Foxglove need the definition of every message type in the bag; the Jazzy
typestore of rosbags knows the common interfaces, and ours are read from the installed
``activesurv_interfaces`` package (its ``share/.../msg/*.msg``) and registered before writing.
Reading uses the definitions stored in the bag itself, so a bag from another version still opens.
"""

from __future__ import annotations

import importlib
import json
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import StoragePlugin
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from activesurv_bringup.errors import BagError
from activesurv_common.ros import topics

RUN_INFO_TOPIC = topics.RUN_INFO


def message_class(type_name: str) -> Any:
    """The Python class of ``pkg/msg/Name`` (the message package must be importable)."""
    pkg, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


def interface_dir() -> Path:
    """The installed ``activesurv_interfaces`` message definitions."""
    try:
        from ament_index_python.packages import get_package_share_directory

        d = Path(get_package_share_directory('activesurv_interfaces')) / 'msg'
        if d.is_dir():
            return d
    except (ImportError, LookupError, OSError):
        pass
    import sys

    d = Path(sys.prefix) / 'share' / 'activesurv_interfaces' / 'msg'
    if d.is_dir():
        return d
    raise BagError('cannot find the activesurv_interfaces message definitions')


def typestore() -> Any:
    """Jazzy typestore with the activesurv message types registered."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    types: dict[str, Any] = {}
    for f in sorted(interface_dir().glob('*.msg')):
        types.update(get_types_from_msg(f.read_text(), f'activesurv_interfaces/msg/{f.stem}'))
    ts.register(types)
    return ts


@dataclass
class BagWriter:
    """An open MCAP bag; connections are added as topics appear."""

    path: Path
    writer: Any
    ts: Any
    connections: dict[str, Any]

    def connection(self, topic: str, msgtype: str, qos: Any = None) -> Any:
        """The bag connection of ``topic`` (added on first use, with the offered QoS)."""
        conn = self.connections.get(topic)
        if conn is None:
            try:
                conn = self.writer.add_connection(
                    topic,
                    msgtype,
                    typestore=self.ts,
                    serialization_format='cdr',
                    offered_qos_profiles=[qos] if qos is not None else (),
                )
            except Exception as exc:
                raise BagError(f'cannot record {topic} ({msgtype}): {exc}') from exc
            self.connections[topic] = conn
        return conn

    def write_raw(self, topic: str, msgtype: str, t_ns: int, data: bytes) -> None:
        self.writer.write(self.connection(topic, msgtype), t_ns, data)

    def write_json(self, topic: str, t_ns: int, obj: Any) -> None:
        """A std_msgs/String with a JSON document (run information, results)."""
        msg = self.ts.types['std_msgs/msg/String'](data=json.dumps(obj))
        self.writer.write(
            self.connection(topic, 'std_msgs/msg/String'),
            t_ns,
            self.ts.serialize_cdr(msg, 'std_msgs/msg/String'),
        )

    def flush(self) -> None:
        """Write the pending MCAP chunk and push it to the disk.

        rosbags buffers messages in memory until a chunk reaches 1 MiB; after this call every
        message written so far survives a SIGKILL (``activesurv bag reindex`` recovers them).
        """
        storage = getattr(self.writer, 'storage', None)
        chunk = getattr(storage, 'chunk', None)
        if storage is None or chunk is None or not hasattr(storage, 'close_chunk'):
            return
        if chunk.bio.tell():
            storage.close_chunk()
        storage.bio.flush()
        os.fsync(storage.bio.fileno())

    def close(self) -> None:
        self.writer.close()


def open_writer(path: Path) -> BagWriter:
    """Create an MCAP rosbag2 bag directory at ``path`` (it must not exist).

    Raises:
        BagError: if the directory exists or cannot be written.
    """
    if path.exists():
        raise BagError(f'bag {path} already exists; choose a new directory')
    try:
        writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.open()
    except Exception as exc:
        raise BagError(f'cannot create bag {path}: {exc}') from exc
    return BagWriter(path, writer, typestore(), {})


@dataclass(frozen=True)
class BagMessage:
    topic: str
    msgtype: str
    t_ns: int
    msg: Any
    raw: bytes


def read_bag(path: Path, topics: set[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a bag in time order, deserialised with the definitions stored in it.

    Raises:
        BagError: for a missing, truncated or corrupt bag (what could be read was yielded).
    """
    if not Path(path).exists():
        raise BagError(f'no bag at {path}')
    from activesurv_bringup.salvage import needs_reindex

    if needs_reindex(Path(path)):
        raise BagError(
            f'bag {path} has no metadata.yaml (its recorder was killed?); '
            f'recover it with: activesurv bag reindex {path}'
        )
    ts = typestore()
    try:
        with Reader(path) as reader:
            types: dict[str, Any] = {}
            for c in reader.connections:
                if c.msgtype not in ts.types and c.msgdef.data:
                    types.update(get_types_from_msg(c.msgdef.data, c.msgtype))
            if types:
                ts.register(types)
            conns = [c for c in reader.connections if topics is None or c.topic in topics]
            for conn, t_ns, raw in reader.messages(connections=conns):
                yield BagMessage(
                    conn.topic,
                    conn.msgtype,
                    t_ns,
                    ts.deserialize_cdr(raw, conn.msgtype),
                    bytes(raw),
                )
    except BagError:
        raise
    except Exception as exc:
        raise BagError(f'bag {path} is unreadable or damaged: {exc}') from exc


def run_info(path: Path) -> dict[str, Any]:
    """The run description the orchestrator stored in the bag."""
    for m in read_bag(path, {RUN_INFO_TOPIC}):
        return dict(json.loads(m.msg.data))
    raise BagError(f'bag {path} has no {RUN_INFO_TOPIC} message (not an activesurv run?)')
