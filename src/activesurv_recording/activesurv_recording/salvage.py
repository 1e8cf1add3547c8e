"""Recover the messages of a bag whose writer died (SIGKILL, power loss): ``bag reindex``.

A killed recorder leaves an MCAP file without its summary and footer, and a bag directory
without ``metadata.yaml``; neither ``ros2 bag`` nor rosbags opens it. The recorder flushes a
complete MCAP chunk every ``flush_period`` seconds, so the file holds every message up to the
last flush followed by at most one partial record. :func:`scan_mcap` reads the records in file
order and stops at the first incomplete or damaged one; :func:`reindex` writes the recovered
messages into a new, indexed bag at the original path and keeps the damaged directory next to
it (``<bag>.damaged``), so nothing is deleted.

The scan follows the MCAP specification (records: opcode, uint64 length, content; schema,
channel and message records at top level or inside uncompressed or zstd/lz4 chunks).
"""

from __future__ import annotations

import shutil
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from activesurv_recording.bagio import needs_reindex as needs_reindex  # re-exported
from activesurv_recording.bagio import typestore
from activesurv_recording.errors import BagError

MAGIC = b'\x89MCAP0\r\n'
OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x03, 0x04, 0x05, 0x06


@dataclass(frozen=True)
class McapSchema:
    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class McapChannel:
    id: int
    schema_id: int
    topic: str
    encoding: str
    metadata: dict[str, str]


@dataclass
class ScanResult:
    """What a sequential scan of an MCAP file recovered."""

    schemas: dict[int, McapSchema] = field(default_factory=dict)
    channels: dict[int, McapChannel] = field(default_factory=dict)
    messages: list[tuple[int, int, bytes]] = field(default_factory=list)  # channel, t_ns, data
    bytes_read: int = 0
    bytes_total: int = 0
    complete: bool = False  # the footer was reached
    stop_reason: str = ''


class _DamagedError(Exception):
    pass


def _string(buf: bytes, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from('<I', buf, pos)
    end = pos + 4 + n
    if end > len(buf):
        raise _DamagedError('string runs past its record')
    return buf[pos + 4 : end].decode('utf-8'), end


def _records(buf: bytes, result: ScanResult, top: bool) -> None:
    """Parse records of ``buf`` into ``result``; raise ``_DamagedError`` at the first bad one."""
    pos = 0
    while pos < len(buf):
        if pos + 9 > len(buf):
            raise _DamagedError(f'record header cut at byte {pos}')
        op = buf[pos]
        (size,) = struct.unpack_from('<Q', buf, pos + 1)
        start, end = pos + 9, pos + 9 + size
        if end > len(buf):
            raise _DamagedError(f'record 0x{op:02x} of {size} bytes cut at byte {len(buf)}')
        body = buf[start:end]
        try:
            _record(op, body, result, top)
        except (struct.error, UnicodeDecodeError, ValueError) as exc:
            raise _DamagedError(f'record 0x{op:02x} at byte {pos} is damaged: {exc}') from exc
        pos = end
        if top:
            result.bytes_read = pos
            if op == 0x02:  # footer
                result.complete = True
                return


def _record(op: int, body: bytes, result: ScanResult, top: bool) -> None:
    if op == OP_SCHEMA:
        (sid,) = struct.unpack_from('<H', body, 0)
        name, p = _string(body, 2)
        enc, p = _string(body, p)
        (n,) = struct.unpack_from('<I', body, p)
        result.schemas[sid] = McapSchema(sid, name, enc, body[p + 4 : p + 4 + n])
    elif op == OP_CHANNEL:
        cid, sid = struct.unpack_from('<HH', body, 0)
        topic, p = _string(body, 4)
        enc, p = _string(body, p)
        (n,) = struct.unpack_from('<I', body, p)
        meta: dict[str, str] = {}
        q, end = p + 4, p + 4 + n
        while q < end:
            k, q = _string(body, q)
            v, q = _string(body, q)
            meta[k] = v
        result.channels[cid] = McapChannel(cid, sid, topic, enc, meta)
    elif op == OP_MESSAGE:
        cid, _seq, log_time, _pub = struct.unpack_from('<HIQQ', body, 0)
        result.messages.append((cid, log_time, body[22:]))
    elif op == OP_CHUNK:
        if not top:
            raise ValueError('nested chunk')
        _t0, _t1, usize, _crc = struct.unpack_from('<QQQI', body, 0)
        compression, p = _string(body, 28)
        (csize,) = struct.unpack_from('<Q', body, p)
        data = body[p + 8 : p + 8 + csize]
        if len(data) != csize:
            raise ValueError('chunk data cut')
        raw = _decompress(data, compression, usize)
        # A chunk is all or nothing: parse into a scratch result, then merge.
        part = ScanResult(schemas=dict(result.schemas), channels=dict(result.channels))
        _records(raw, part, top=False)
        result.schemas, result.channels = part.schemas, part.channels
        result.messages.extend(part.messages)


def _decompress(data: bytes, compression: str, size: int) -> bytes:
    if compression == '':
        raw = data
    elif compression == 'zstd':
        try:
            from compression import zstd  # type: ignore[import-not-found]

            raw = zstd.decompress(data)
        except ImportError:
            import zstandard

            raw = zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    elif compression == 'lz4':
        from lz4.frame import decompress  # type: ignore[import-untyped]

        raw = decompress(data)
    else:
        raise ValueError(f'unknown chunk compression {compression!r}')
    if len(raw) != size:
        raise ValueError(f'chunk decompressed to {len(raw)} bytes, expected {size}')
    return bytes(raw)


def scan_mcap(path: Path) -> ScanResult:
    """Read the records of an MCAP file in order, up to the first incomplete or damaged one.

    Raises:
        BagError: if the file is missing or is not MCAP at all.
    """
    try:
        buf = Path(path).read_bytes()
    except OSError as exc:
        raise BagError(f'cannot read {path}: {exc}') from exc
    if not buf.startswith(MAGIC):
        raise BagError(f'{path} is not an MCAP file (bad magic)')
    result = ScanResult(bytes_total=len(buf))
    body = buf[len(MAGIC) :]
    try:
        _records(body, result, top=True)
        result.stop_reason = 'footer reached' if result.complete else 'end of file'
    except _DamagedError as exc:
        result.stop_reason = str(exc)
    result.bytes_read += len(MAGIC)
    return result


@dataclass(frozen=True)
class ReindexReport:
    bag: Path
    damaged: Path
    messages: int
    topics: int
    last_time_ns: int
    bytes_recovered: int
    bytes_total: int
    stop_reason: str
    skipped_topics: tuple[str, ...]

    def as_dict(self) -> dict[str, Any]:
        return {
            'bag': str(self.bag),
            'damaged_copy': str(self.damaged),
            'messages': self.messages,
            'topics': self.topics,
            'last_time_ns': self.last_time_ns,
            'bytes_recovered': self.bytes_recovered,
            'bytes_total': self.bytes_total,
            'stop_reason': self.stop_reason,
            'skipped_topics': list(self.skipped_topics),
        }


def reindex(bag: Path) -> ReindexReport:
    """Rebuild ``bag`` from what its MCAP files hold; the original moves to ``<bag>.damaged``.

    Raises:
        BagError: if ``bag`` has no MCAP file, nothing can be recovered, or the new bag
            cannot be written (then the original is left where it was).
    """
    # rosbags' writer and type system only when a bag is rebuilt
    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.enums import StoragePlugin
    from rosbags.rosbag2.storage_mcap import get_qos
    from rosbags.typesys import get_types_from_msg

    bag = Path(bag)
    files = sorted(bag.glob('*.mcap')) if bag.is_dir() else []
    if not files:
        raise BagError(f'{bag} holds no .mcap file to reindex')
    scans = [scan_mcap(f) for f in files]
    damaged = bag.with_name(bag.name + '.damaged')
    if damaged.exists():
        raise BagError(f'{damaged} exists already; move it away first')
    ts = typestore()
    tmp = bag.with_name(bag.name + '.reindex-tmp')
    if tmp.exists():
        shutil.rmtree(tmp)
    writer = Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    count, last, skipped = 0, 0, set()
    conns: dict[tuple[int, int], Any] = {}
    try:
        for i, scan in enumerate(scans):
            for cid, ch in scan.channels.items():
                schema = scan.schemas.get(ch.schema_id)
                if schema is None:
                    skipped.add(ch.topic)
                    continue
                if schema.name not in ts.types and schema.encoding == 'ros2msg':
                    try:
                        text = schema.data.decode().split('=' * 80)[0]
                        ts.register(get_types_from_msg(text, schema.name))
                    except Exception:
                        skipped.add(ch.topic)
                        continue
                if schema.name not in ts.types:
                    skipped.add(ch.topic)
                    continue
                qos_text = ch.metadata.get('offered_qos_profiles', '')
                qos = get_qos(_meta_bytes('offered_qos_profiles', qos_text)) if qos_text else []
                conns[(i, cid)] = writer.add_connection(
                    ch.topic,
                    schema.name,
                    typestore=ts,
                    serialization_format=ch.encoding or 'cdr',
                    offered_qos_profiles=qos,
                )
            for cid, t_ns, data in scan.messages:
                conn = conns.get((i, cid))
                if conn is None:
                    continue
                writer.write(conn, t_ns, data)
                count += 1
                last = max(last, t_ns)
        writer.close()
    except Exception as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        raise BagError(f'cannot rebuild {bag}: {exc}') from exc
    if count == 0:
        shutil.rmtree(tmp, ignore_errors=True)
        raise BagError(f'{bag}: no complete message could be recovered ({scans[0].stop_reason})')
    bag.rename(damaged)
    tmp.rename(bag)
    # The MCAP file inside is named after the directory it was written in.
    for f in bag.glob('*.mcap'):
        f.rename(bag / f'{bag.name}.mcap')
    meta = bag / 'metadata.yaml'
    meta.write_text(meta.read_text().replace(f'{tmp.name}.mcap', f'{bag.name}.mcap'))
    return ReindexReport(
        bag,
        damaged,
        count,
        len(conns),
        last,
        sum(s.bytes_read for s in scans),
        sum(s.bytes_total for s in scans),
        '; '.join(s.stop_reason for s in scans),
        tuple(sorted(skipped)),
    )


def _meta_bytes(key: str, value: str) -> bytes:
    k, v = key.encode(), value.encode()
    return struct.pack('<I', len(k)) + k + struct.pack('<I', len(v)) + v
