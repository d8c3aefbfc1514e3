"""A rosbag2 writer that counts what it writes (ROS-free; the ``rosbags`` library).

Used by the ``recorder`` node (raw CDR from rclpy) and by the in-process runner (messages
serialised here), so that both produce the same bag layout: rosbag2 version 9, MCAP storage by
default, as ROS 2 Jazzy's ``ros2 bag record``.
"""

from __future__ import annotations

import struct
import threading
from collections import Counter, deque
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


class QueuedBagWriter:
    """A :class:`BagWriter` whose writes are made by a thread of its own.

    For a recorder composed with the control nodes (``wavelet_stack``): :meth:`write_raw` only
    queues the bytes (an append, well under a microsecond), and the thread writes the queue
    every ``period`` s. The control thread then never waits for the file (a slow disk stalls
    the thread, not the loop; the queue holds what is not yet written, nothing is dropped), and
    the bag's Python work runs in batches instead of between two samples. Same parameters as
    :class:`BagWriter`, plus ``period`` (s).
    """

    def __init__(self, path: str | Path, storage: str = "mcap", period: float = 0.02) -> None:
        self._bag = BagWriter(path, storage)
        self.path = self._bag.path
        self._queue: deque[tuple[str, int, bytes]] = deque()
        self._lock = threading.Lock()  # the bag: the thread's writes, add_topic, close
        self._stop = threading.Event()
        self._period = float(period)
        self.error: Exception | None = None  # the first write that failed
        self.failed = 0  # messages whose write failed (lost)
        self._thread = threading.Thread(target=self._run, name="bag_writer", daemon=True)
        self._thread.start()

    @property
    def counts(self) -> Counter[str]:
        """Messages written so far per topic (queued ones not yet counted)."""
        return self._bag.counts

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` has run."""
        return self._bag.closed

    @property
    def queued(self) -> int:
        """Messages waiting for the thread."""
        return len(self._queue)

    def add_topic(self, topic: str, msgtype: str) -> None:
        """As :meth:`BagWriter.add_topic` (at once, in the caller's thread)."""
        with self._lock:
            self._bag.add_topic(topic, msgtype)

    def write_raw(self, topic: str, t_ns: int, raw: bytes) -> None:
        """Queue serialised bytes of a declared topic at ``t_ns`` (ns) for the thread."""
        self._queue.append((topic, t_ns, raw))

    def _write_queued(self) -> None:
        with self._lock:
            queue, write = self._queue, self._bag.write_raw
            while queue:
                item = queue.popleft()
                try:
                    write(*item)
                except Exception as exc:  # the thread must go on: keep the first, count it
                    self.error = self.error or exc
                    self.failed += 1

    def _run(self) -> None:
        while not self._stop.wait(self._period):
            self._write_queued()

    def close(self) -> None:
        """Write what is queued, stop the thread, finish the bag; safe to call twice."""
        self._stop.set()
        self._thread.join()
        self._write_queued()
        with self._lock:
            self._bag.close()
