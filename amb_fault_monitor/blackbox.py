"""
Black box: a ring buffer of the latest serialised messages, written to its own bag per event.

The node hands every received message (serialised CDR bytes, its topic as recorded and its
type) to :meth:`BlackBox.add`, with its header stamp in ns. The buffer keeps ``pre_s``
seconds (by stamp) before the newest message. :meth:`trigger` (at an event) marks the event
time; messages keep being added until their stamps pass ``trigger + post_s``, then the bag is
written (pre- and post-trigger together) with :class:`amb_tools.bag_writer.BagWriter` into
``folder/<name>`` and :meth:`add` returns its path. A trigger while a capture is open extends
nothing: the second event falls inside the first bag (its name is recorded in the result).
"""

from __future__ import annotations

from collections import deque
from pathlib import Path

from amb_fault_monitor.errors import FaultMonitorError

__all__ = ["BlackBox"]


class BlackBox:
    """
    Pre/post-trigger capture of serialised messages into a rosbag2 per event.

    Parameters
    ----------
    folder : str or Path
        Where the bags go (created if missing).
    pre_s, post_s : float
        Seconds kept before and recorded after a trigger (>= 0), by message stamp.
    storage : str
        ``mcap`` (Jazzy's default) or ``sqlite3``.
    """

    def __init__(
        self, folder: str | Path, pre_s: float, post_s: float, storage: str = "mcap"
    ) -> None:
        if not (pre_s >= 0 and post_s >= 0):
            raise FaultMonitorError(f"pre_s and post_s must be >= 0 s, got {pre_s}, {post_s}")
        self.folder = Path(folder)
        self.pre_ns = round(pre_s * 1e9)
        self.post_ns = round(post_s * 1e9)
        self.storage = storage
        self._buf: deque[tuple[str, str, int, bytes]] = deque()
        self._capture: dict | None = None
        self.written: list[Path] = []

    @property
    def capturing(self) -> bool:
        """True between a trigger and the write of its bag."""
        return self._capture is not None

    def add(self, topic: str, msgtype: str, t_ns: int, raw: bytes) -> Path | None:
        """
        Buffer one message; return the bag path if this message completed a capture.

        Parameters
        ----------
        topic : str
            Topic name as recorded (e.g. ``/amb/measurement``).
        msgtype : str
            ROS type, e.g. ``amb_msgs/msg/Measurement``.
        t_ns : int
            Header stamp, ns.
        raw : bytes
            CDR bytes (``rclpy.serialization.serialize_message``).
        """
        t_ns = int(t_ns)
        self._buf.append((topic, msgtype, t_ns, bytes(raw)))
        cap = self._capture
        if cap is not None:
            if t_ns >= cap["end"]:
                return self._write()
            return None
        while self._buf and self._buf[0][2] < t_ns - self.pre_ns:
            self._buf.popleft()
        return None

    def trigger(self, t_ns: int, name: str) -> bool:
        """
        Start a capture at stamp ``t_ns`` (ns) for a bag called ``name``.

        Returns
        -------
        bool
            False if a capture is already open (this event is inside it).
        """
        if self._capture is not None:
            self._capture["names"].append(name)
            return False
        self._capture = {"end": int(t_ns) + self.post_ns, "names": [name], "start": int(t_ns)}
        return True

    def flush(self) -> Path | None:
        """Write an open capture now (shutdown); return its path or None."""
        return self._write() if self._capture is not None else None

    def _write(self) -> Path:
        from amb_tools.bag_writer import BagWriter

        cap = self._capture
        self._capture = None
        path = self.folder / cap["names"][0]
        k = 1
        while path.exists():
            path = self.folder / f"{cap['names'][0]}_{k}"
            k += 1
        lo = cap["start"] - self.pre_ns
        with BagWriter(path, self.storage) as bag:
            for topic, msgtype, t_ns, raw in self._buf:
                if t_ns >= lo:
                    bag.add_topic(topic, msgtype)
                    bag.write_raw(topic, t_ns, raw)
        self.written.append(path)
        # keep the pre-trigger window for the next event
        newest = self._buf[-1][2] if self._buf else 0
        while self._buf and self._buf[0][2] < newest - self.pre_ns:
            self._buf.popleft()
        return path
