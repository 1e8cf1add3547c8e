"""rosbag2 I/O with the ``rosbags`` library: MCAP bags with our message definitions inside.

``ros2 bag`` and Foxglove need the definition of every message type in the bag; the Jazzy
typestore of rosbags knows the common interfaces, and ours are read from the installed
``activesurv_interfaces`` package (its ``share/.../msg/*.msg``) and registered before writing.
Reading uses the definitions stored in the bag itself, so a bag from another version still opens.
"""

from __future__ import annotations

import json
import os
import struct
import sys
from collections.abc import Iterator
from collections.abc import Set as AbstractSet
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import StoragePlugin
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from activesurv_common.ros import topics
from activesurv_recording.errors import BagError

RUN_INFO_TOPIC = topics.RUN_INFO


def interface_dir() -> Path:
    """The installed ``activesurv_interfaces`` message definitions."""
    try:
        # optional: only a colcon install has an ament index
        from ament_index_python.packages import get_package_share_directory

        d = Path(get_package_share_directory('activesurv_interfaces')) / 'msg'
        if d.is_dir():
            return d
    except (ImportError, LookupError, OSError):
        pass

    d = Path(sys.prefix) / 'share' / 'activesurv_interfaces' / 'msg'
    if d.is_dir():
        return d
    raise BagError('cannot find the activesurv_interfaces message definitions')


def our_types() -> dict[str, Any]:
    """Today's activesurv message types (from the installed definitions)."""
    types: dict[str, Any] = {}
    for f in sorted(interface_dir().glob('*.msg')):
        types.update(get_types_from_msg(f.read_text(), f'activesurv_interfaces/msg/{f.stem}'))
    return types


def typestore() -> Any:
    """Jazzy typestore with the activesurv message types registered."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    ts.register(our_types())
    return ts


def reading_typestore(connections: Any) -> Any:
    """A typestore for reading a bag: every type as the bag's own definitions have it (a bag
    recorded before a message gained a field reads as it was written), today's definitions
    only for types the bag does not define."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    types: dict[str, Any] = {}
    for c in connections:
        if c.msgdef.data and c.msgtype not in ts.types:
            types.update(get_types_from_msg(c.msgdef.data, c.msgtype))
    types = {k: v for k, v in types.items() if k not in ts.types}
    for k, v in our_types().items():
        types.setdefault(k, v)
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
        """The bag connection of ``topic`` (added on first use, with the offered QoS: one
        profile or a list, one per publisher)."""
        conn = self.connections.get(topic)
        if conn is None:
            profiles = [] if qos is None else list(qos) if isinstance(qos, list) else [qos]
            try:
                conn = self.writer.add_connection(
                    topic,
                    msgtype,
                    typestore=self.ts,
                    serialization_format='cdr',
                    offered_qos_profiles=profiles,
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


class SplitBagWriter:
    """A bag split into files of at most ``max_duration`` (bag time), as ``ros2 bag record
    --max-bag-duration`` does: ``bag_0.mcap``, ``bag_1.mcap``, ... in the bag directory,
    listed in one ``metadata.yaml`` (rewritten at every split, so the finished files are a
    readable bag at any moment). The open file is written in a hidden ``.split_N`` directory
    and moved in when it is closed. Every file declares the topics in the same order (the same
    MCAP channel ids, which readers of split bags rely on) and starts with the last message of
    every latched topic recorded so far and the run information, so it replays on its own.

    Raises:
        BagError: as :func:`open_writer`.
    """

    def __init__(
        self,
        path: Path,
        max_duration: float,
        latched: set[str] | None = None,
        keep: int = 0,
        max_bytes: int = 0,
    ) -> None:
        if path.exists():
            raise BagError(f'bag {path} already exists; choose a new directory')
        if not (max_duration > 0.0 or max_bytes > 0):
            raise BagError(f'max bag duration must be > 0 s, got {max_duration}')
        path.mkdir(parents=True)
        self.path = path
        self.max_ns = int(max_duration * 1e9) if max_duration > 0.0 else 2**62
        self.keep = int(keep)  # newest files kept (0: all): retention for sessions of hours
        self.max_bytes = int(max_bytes)  # a file is closed once it holds this many (0: never)
        self.removed: list[str] = []
        self._latest = 0
        self.latched = latched if latched is not None else set()
        self.ts = typestore()
        self.index = 0
        self.closed: list[dict[str, Any]] = []
        self._topics: dict[str, tuple[str, Any]] = {}  # in the order they appeared
        self._last: dict[str, tuple[str, bytes]] = {}
        self._start: int | None = None
        self._open(None)

    def _split_dir(self, n: int) -> Path:
        return self.path / f'.split_{n}'

    def _open(self, t_ns: int | None) -> None:
        d = self._split_dir(self.index)
        try:
            w = Writer(d, version=9, storage_plugin=StoragePlugin.MCAP)
            w.open()
        except Exception as exc:
            raise BagError(f'cannot create bag file in {d}: {exc}') from exc
        self.current = BagWriter(d, w, self.ts, {})
        self._start = t_ns
        for topic, (msgtype, qos) in self._topics.items():
            self.current.connection(topic, msgtype, qos)
        if t_ns is not None:
            for topic, (msgtype, data) in self._last.items():
                self.current.write_raw(topic, msgtype, t_ns, data)

    def _rotate(self) -> None:
        self.current.close()
        d = self._split_dir(self.index)
        name = f'{self.path.name}_{self.index}.mcap'
        (d / f'{d.name}.mcap').rename(self.path / name)
        meta = yaml.safe_load((d / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
        (d / 'metadata.yaml').unlink()
        d.rmdir()
        for f in meta.get('files') or []:
            f['path'] = name
        meta['relative_file_paths'] = [name]
        self.closed.append(meta)
        while self.keep and len(self.closed) > self.keep:  # the oldest files go (asked for)
            old = self.closed.pop(0)
            for f in old['relative_file_paths']:
                (self.path / f).unlink(missing_ok=True)
                self.removed.append(f)
        write_merged_metadata(self.path, self.closed)
        self.index += 1

    def connection(self, topic: str, msgtype: str, qos: Any = None) -> Any:
        self._topics.setdefault(topic, (msgtype, qos))
        return self.current.connection(topic, msgtype, qos)

    def write_raw(self, topic: str, msgtype: str, t_ns: int, data: bytes) -> None:
        self._topics.setdefault(topic, (msgtype, None))
        self._latest = max(self._latest, t_ns)
        if self._start is None:
            self._start = t_ns
        elif t_ns - self._start >= self.max_ns:
            self._rotate()
            self._open(t_ns)
        if topic in self.latched or topic == RUN_INFO_TOPIC:
            self._last[topic] = (msgtype, bytes(data))
        self.current.write_raw(topic, msgtype, t_ns, data)

    def write_json(self, topic: str, t_ns: int, obj: Any) -> None:
        msg = self.ts.types['std_msgs/msg/String'](data=json.dumps(obj))
        data = self.ts.serialize_cdr(msg, 'std_msgs/msg/String')
        self.write_raw(topic, 'std_msgs/msg/String', t_ns, bytes(data))

    def flush(self) -> None:
        self.current.flush()
        if self.max_bytes and self._start is not None:
            d = self._split_dir(self.index)
            if sum(f.stat().st_size for f in d.glob('*.mcap')) >= self.max_bytes:
                self._rotate()
                self._open(self._latest)  # the next file starts with the latched messages

    def close(self) -> None:
        self._rotate()


def write_merged_metadata(path: Path, parts: list[dict[str, Any]]) -> None:
    """``metadata.yaml`` of a bag made of the files described by ``parts`` (each the
    ``rosbag2_bagfile_information`` of one file)."""
    first = dict(parts[0])
    starts = [int(p['starting_time']['nanoseconds_since_epoch']) for p in parts]
    ends = [s + int(p['duration']['nanoseconds']) for s, p in zip(starts, parts, strict=True)]
    topics: dict[str, dict[str, Any]] = {}
    for p in parts:
        for t in p.get('topics_with_message_count') or []:
            name = t['topic_metadata']['name']
            if name in topics:
                topics[name]['message_count'] += int(t['message_count'])
            else:
                topics[name] = {
                    'message_count': int(t['message_count']),
                    'topic_metadata': t['topic_metadata'],
                }
    first.update(
        relative_file_paths=[f for p in parts for f in p['relative_file_paths']],
        files=[f for p in parts for f in (p.get('files') or [])],
        message_count=sum(int(p['message_count']) for p in parts),
        starting_time={'nanoseconds_since_epoch': min(starts)},
        duration={'nanoseconds': max(ends) - min(starts)},
        topics_with_message_count=[topics[k] for k in sorted(topics)],
    )
    tmp = path / 'metadata.yaml.tmp'
    tmp.write_text(yaml.safe_dump({'rosbag2_bagfile_information': first}, sort_keys=False))
    tmp.replace(path / 'metadata.yaml')


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


def cdr_header(data: bytes) -> tuple[float, str]:
    """(stamp in s, frame_id) of a serialized message that starts with a std_msgs/Header.

    Raises:
        ValueError: if the bytes are not a CDR message with a header.
    """
    if len(data) < 16 or data[0] != 0:
        raise ValueError('not a CDR-encapsulated message')
    order = '<' if data[1] & 1 else '>'
    sec, nanosec, n = struct.unpack_from(f'{order}iII', data, 4)
    if n == 0 or 16 + n > len(data):
        raise ValueError('bad frame_id length in the header')
    return sec + 1e-9 * nanosec, data[16 : 16 + n - 1].decode('utf-8', 'replace')


def strip_namespace(topic: str, namespace: str) -> str:
    """The name ``topic`` is recorded under: a rig's namespace left out (``/rig1/x`` -> ``/x``),
    so that the bags of a namespaced hardware run read as every other run's."""
    ns = namespace.strip('/')
    prefix = f'/{ns}/' if ns else ''
    return '/' + topic[len(prefix) :] if prefix and topic.startswith(prefix) else topic


def needs_reindex(bag: Path) -> bool:
    """A bag directory with MCAP data but no ``metadata.yaml`` (its writer died)."""
    bag = Path(bag)
    return bag.is_dir() and not (bag / 'metadata.yaml').exists() and any(bag.glob('*.mcap'))


def read_bag(path: Path, topics: AbstractSet[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a bag in time order, deserialised with the definitions stored in it.

    Raises:
        BagError: for a missing, truncated or corrupt bag (what could be read was yielded).
    """
    if not Path(path).exists():
        raise BagError(f'no bag at {path}')
    if needs_reindex(Path(path)):
        raise BagError(
            f'bag {path} has no metadata.yaml (its recorder was killed?); '
            f'recover it with: activesurv bag reindex {path}'
        )
    try:
        with Reader(path) as reader:
            ts = reading_typestore(reader.connections)
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


def offered_qos(path: Path) -> dict[str, list[Any]]:
    """The QoS profiles each topic's publishers offered, as recorded in the bag's metadata.

    Raises:
        BagError: for a missing or unreadable bag.
    """
    try:
        with Reader(path) as reader:
            out: dict[str, list[Any]] = {}
            for c in reader.connections:
                out.setdefault(c.topic, []).extend(getattr(c.ext, 'offered_qos_profiles', []))
            return out
    except Exception as exc:
        raise BagError(f'bag {path} is unreadable or damaged: {exc}') from exc
