"""Raw (serialized) rosbag2 access through `rosbags`, shared by the logger, the player and the bag tools.

Messages are kept as CDR bytes end to end: the recorder writes what it received, the player publishes
what was written, so a record/replay round trip is lossless by construction.

Durability: rosbags keeps MCAP chunks (up to 1 MiB) in memory and commits sqlite3 only at close.
:class:`RawBagWriter` flushes a chunk / commits at least every ``flush_period_s`` so that, after a crash,
everything older than that is on disk; ``reindex_bag`` (see :mod:`robot_bridge.bagio.reindex`) then
rebuilds a readable bag, as ``ros2 bag reindex`` does.
"""
from __future__ import annotations

import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
STORAGES = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}


class BagError(ValueError):
    """A bag that cannot be used: missing, empty, corrupt, or not in the contract format."""


@dataclass(frozen=True)
class RawMessage:
    topic: str
    msgtype: str          # e.g. 'sensor_msgs/msg/JointState'
    timestamp_ns: int     # the bag's (receive) time stamp
    data: bytes           # CDR with encapsulation header, as rmw serializes it


def storage_plugin(storage: str) -> StoragePlugin:
    try:
        return STORAGES[storage]
    except KeyError:
        raise BagError(f"unknown storage '{storage}': use one of {sorted(STORAGES)}") from None


class RawBagWriter:
    """Write serialized messages to a new rosbag2 (format version 9, as Jazzy's rosbag2).

    Topics are added on first use. ``flush()`` makes everything written so far durable; ``write`` calls it
    automatically when ``flush_period_s`` has passed since the last flush.
    """

    def __init__(self, path: str | Path, storage: str = 'mcap', flush_period_s: float = 0.5):
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f'output bag {self.path} already exists; choose a new directory')
        plugin = storage_plugin(storage)
        parent = self.path.resolve().parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise BagError(f'cannot create bag {self.path}: {exc.strerror} ({parent})') from None
        self._writer = Writer(self.path, version=9, storage_plugin=plugin)
        try:
            self._writer.open()
        except Exception as exc:    # OSError, rosbags' WriterError: not writable, no space, ...
            shutil.rmtree(self.path, ignore_errors=True)
            raise BagError(f'cannot create bag {self.path}: {exc}') from None
        self._connections = {}
        self._flush_period_s = flush_period_s
        self._last_flush = time.monotonic()
        self.count = 0

    def write(self, topic: str, msgtype: str, timestamp_ns: int, data: bytes) -> None:
        conn = self._connections.get(topic)
        if conn is None:
            conn = self._writer.add_connection(topic, msgtype, typestore=TYPESTORE)
            self._connections[topic] = conn
        elif conn.msgtype != msgtype:
            raise BagError(f'topic {topic} changed type from {conn.msgtype} to {msgtype}')
        self._writer.write(conn, int(timestamp_ns), bytes(data))
        self.count += 1
        if time.monotonic() - self._last_flush >= self._flush_period_s:
            self.flush()

    def flush(self) -> None:
        """Push buffered messages to disk (an MCAP chunk, or an sqlite3 commit)."""
        storage = self._writer.storage
        if hasattr(storage, 'close_chunk'):          # MCAP: close the pending chunk and flush the file
            if storage.chunk.msgs:
                storage.close_chunk()
            storage.bio.flush()
        elif hasattr(storage, 'conn'):               # sqlite3: commit the open transaction
            storage.conn.commit()
        self._last_flush = time.monotonic()

    def close(self) -> None:
        """Finish the storage file and write metadata.yaml."""
        self._writer.close()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close()
        if exc_type is not None:      # a bag written in one go that failed half-way is not a result
            shutil.rmtree(self.path, ignore_errors=True)


def open_reader(path: str | Path) -> AnyReader:
    """Open a bag for reading, turning every failure into one clear :class:`BagError`."""
    path = Path(path)
    if not path.exists():
        raise BagError(f'bag {path} does not exist')
    if path.is_dir() and not (path / 'metadata.yaml').exists():
        raise BagError(f'{path} has no metadata.yaml: not a rosbag2, or not closed cleanly '
                       f"(run 'bag-tools reindex {path}' to recover it)")
    if path.is_file() and path.suffix not in ('.mcap', '.db3'):
        raise BagError(f'{path} is not a rosbag2: give the bag directory (with metadata.yaml), '
                       f'or an .mcap/.db3 file')
    try:
        reader = AnyReader([path], default_typestore=TYPESTORE)
        reader.open()
    except Exception as exc:  # rosbags raises several types for corrupt files
        raise BagError(f'cannot read bag {path}: {exc}') from None
    return reader


def iter_raw_messages(path: str | Path, topics: list[str] | None = None,
                      start_ns: int | None = None) -> Iterator[RawMessage]:
    """Yield every message of the bag (optionally only ``topics``) in bag-time order."""
    reader = open_reader(path)
    try:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        try:
            for conn, ts, data in reader.messages(connections=conns, start=start_ns):
                yield RawMessage(conn.topic, conn.msgtype, ts, bytes(data))
        except BagError:
            raise
        except Exception as exc:
            raise BagError(f'bag {path} is corrupt: {exc}') from None
    finally:
        reader.close()


def topic_types(path: str | Path) -> dict[str, str]:
    """Topic name -> message type of a bag."""
    reader = open_reader(path)
    try:
        return {c.topic: c.msgtype for c in reader.connections}
    finally:
        reader.close()


def deserialize(data: bytes, msgtype: str):
    """Decode CDR bytes into a rosbags message object."""
    return TYPESTORE.deserialize_cdr(data, msgtype)


def serialize(msg, msgtype: str) -> bytes:
    return bytes(TYPESTORE.serialize_cdr(msg, msgtype))
