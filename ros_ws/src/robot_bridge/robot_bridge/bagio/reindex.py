"""Recover a bag that was not closed (process killed): the equivalent of ``ros2 bag reindex``.

rosbag2 writes metadata.yaml (and MCAP's summary) only at close. This module scans what reached the disk,
tolerating a truncated last record, and rewrites a complete bag. The original directory is kept beside
it as ``<bag>.unindexed`` so nothing is lost.
"""
from __future__ import annotations

import io
import shutil
import sqlite3
import struct
from pathlib import Path
from typing import Iterator

from .raw import BagError, RawBagWriter, RawMessage

MCAP_MAGIC = b'\x89MCAP0\r\n'


def _string(buf: io.BytesIO) -> str:
    (n,) = struct.unpack('<I', buf.read(4))
    return buf.read(n).decode()


def _scan_mcap_records(data: bytes, schemas: dict, channels: dict) -> Iterator[RawMessage]:
    pos = 0
    while pos + 9 <= len(data):
        op = data[pos]
        (length,) = struct.unpack_from('<Q', data, pos + 1)
        body_start, body_end = pos + 9, pos + 9 + length
        if body_end > len(data):      # truncated record: the crash point
            return
        body = data[body_start:body_end]
        if op == 0x03:                # Schema
            buf = io.BytesIO(body)
            (sid,) = struct.unpack('<H', buf.read(2))
            schemas[sid] = _string(buf)
        elif op == 0x04:              # Channel
            buf = io.BytesIO(body)
            cid, sid = struct.unpack('<HH', buf.read(4))
            channels[cid] = (_string(buf), sid)
        elif op == 0x05:              # Message
            cid, _seq, log_time, _pub = struct.unpack_from('<HIQQ', body)
            topic, sid = channels[cid]
            yield RawMessage(topic, schemas[sid], log_time, bytes(body[22:]))
        elif op == 0x06:              # Chunk (uncompressed, as our writer makes them)
            buf = io.BytesIO(body)
            buf.read(28)
            compression = _string(buf)
            (size,) = struct.unpack('<Q', buf.read(8))
            if compression:
                raise BagError(f'cannot reindex a {compression}-compressed MCAP chunk')
            yield from _scan_mcap_records(buf.read(size), schemas, channels)
        pos = body_end


def scan_mcap(path: Path) -> list[RawMessage]:
    data = path.read_bytes()
    if not data.startswith(MCAP_MAGIC):
        raise BagError(f'{path} is not an MCAP file')
    return list(_scan_mcap_records(data[len(MCAP_MAGIC):], {}, {}))


def scan_sqlite3(path: Path) -> list[RawMessage]:
    try:
        con = sqlite3.connect(path)
        topics = {tid: (name, typ) for tid, name, typ in con.execute('SELECT id, name, type FROM topics')}
        rows = con.execute('SELECT topic_id, timestamp, data FROM messages ORDER BY id').fetchall()
        con.close()
    except sqlite3.Error as exc:
        raise BagError(f'cannot read {path}: {exc}') from None
    return [RawMessage(topics[t][0], topics[t][1], ts, bytes(d)) for t, ts, d in rows]


def reindex_bag(bag: str | Path) -> int:
    """Rebuild a complete bag from the storage file in ``bag``; returns the number of messages recovered."""
    bag = Path(bag)
    if not bag.is_dir():
        raise BagError(f'{bag} is not a bag directory')
    files = sorted(bag.glob('*.mcap')) + sorted(bag.glob('*.db3'))
    if not files:
        raise BagError(f'{bag} holds no .mcap or .db3 storage file')
    storage = 'mcap' if files[0].suffix == '.mcap' else 'sqlite3'
    messages = []
    for f in files:
        messages += scan_mcap(f) if storage == 'mcap' else scan_sqlite3(f)
    backup = bag.with_name(bag.name + '.unindexed')
    if backup.exists():
        raise BagError(f'{backup} already exists; move it away first')
    staging = bag.with_name(bag.name + '.reindexing')
    if staging.exists():
        shutil.rmtree(staging)
    staging.mkdir()
    with RawBagWriter(staging / bag.name, storage=storage) as writer:   # same file names as the original
        for m in sorted(messages, key=lambda m: m.timestamp_ns):
            writer.write(m.topic, m.msgtype, m.timestamp_ns, m.data)
    bag.rename(backup)
    (staging / bag.name).rename(bag)
    staging.rmdir()
    return len(messages)
