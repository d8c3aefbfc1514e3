"""A rosbag2 writer that counts what it writes (ROS-free; the ``rosbags`` library).

Used by the ``recorder`` node (raw CDR from rclpy) and by the in-process runner (messages
serialised here), so that both produce the same bag layout: rosbag2 version 9, MCAP storage by
default, as ROS 2 Jazzy's ``ros2 bag record``.
"""

from __future__ import annotations

import struct
from collections import Counter
from pathlib import Path
from typing import Any

from rosbags.rosbag2 import StoragePlugin, Writer

from amb_tools.bag_types import ros_type_name, typestore

STORAGE_PLUGINS = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}


def header_stamp_ns(raw: bytes | memoryview) -> int:
    """Read ``header.stamp`` of a serialised message whose first field is a ``std_msgs/Header``.

    Parameters
    ----------
    raw : bytes
        CDR bytes including the 4-byte encapsulation header.

    Returns
    -------
    int
        The stamp in ns.

    Raises
    ------
    ValueError
        If the buffer is too short or the encapsulation is not plain CDR.
    """
    if len(raw) < 12:
        raise ValueError(f"serialised message of {len(raw)} bytes has no header stamp")
    kind = raw[1]
    if kind not in (0, 1):
        raise ValueError(f"CDR encapsulation kind {kind} is not plain CDR (0 = BE, 1 = LE)")
    sec, nanosec = struct.unpack_from("<iI" if kind == 1 else ">iI", raw, 4)
    return sec * 1_000_000_000 + nanosec


class BagWriter:
    """Write a rosbag2 and count messages per topic.

    Parameters
    ----------
    path : str or pathlib.Path
        Bag folder to create; it must not exist yet.
    storage : {'mcap', 'sqlite3'}
        Storage plugin; ``mcap`` is Jazzy's default.

    Raises
    ------
    FileExistsError
        If ``path`` exists.
    ValueError
        If ``storage`` is unknown.
    """

    def __init__(self, path: str | Path, storage: str = "mcap") -> None:
        if storage not in STORAGE_PLUGINS:
            allowed = sorted(STORAGE_PLUGINS)
            raise ValueError(f"storage {storage!r} unknown; choose one of {allowed}")
        self.path = Path(path)
        if self.path.exists():
            raise FileExistsError(f"bag folder {self.path} exists; choose a new path or remove it")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._store = typestore()
        self._writer = Writer(self.path, version=9, storage_plugin=STORAGE_PLUGINS[storage])
        self._writer.open()
        self._connections: dict[str, Any] = {}
        self.counts: Counter[str] = Counter()
        self.closed = False

    def add_topic(self, topic: str, msgtype: str) -> None:
        """Declare a topic and its type (idempotent for the same type).

        Raises
        ------
        ValueError
            If the topic was declared with another type.
        """
        msgtype = ros_type_name(msgtype)
        conn = self._connections.get(topic)
        if conn is not None:
            if conn.msgtype != msgtype:
                raise ValueError(f"topic {topic} already recorded as {conn.msgtype}, not {msgtype}")
            return
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=self._store
        )

    def write_raw(self, topic: str, t_ns: int, raw: bytes) -> None:
        """Write serialised (CDR) bytes of a declared topic at ``t_ns`` (ns)."""
        self._writer.write(self._connections[topic], int(t_ns), bytes(raw))
        self.counts[topic] += 1

    def write(self, topic: str, t_ns: int, msg: Any) -> None:
        """Serialise a ``rosbags`` message object and write it."""
        conn = self._connections[topic]
        self.write_raw(topic, t_ns, self._store.serialize_cdr(msg, conn.msgtype))

    def close(self) -> None:
        """Finish the bag (metadata, indices); safe to call twice."""
        if not self.closed:
            self._writer.close()
            self.closed = True

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
