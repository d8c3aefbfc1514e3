"""
Black box: a ring buffer of the latest serialised messages, written to its own bag per event.

The node hands every received message (serialised CDR bytes, its topic as recorded and its
type) to :meth:`BlackBox.add`, with its header stamp in ns. Every topic keeps the messages
from ``pre_s`` seconds (by stamp) before the newest stamp of the most lagging topic: streams
arrive with different lags (the coefficients of a sample come after its measurement, and an
event decided on the lagging stream must still find the leading stream's pre-trigger part).
:meth:`trigger` (at an event) marks the event time; messages keep being added until every
topic's stamps have reached ``trigger + post_s`` (or one topic is ``pre_s + post_s + 1`` s
beyond that: a stalled stream does not hold the bag back), then the messages stamped in
``[trigger - pre_s, trigger + post_s]`` are written in stamp order with
:class:`amb_tools.bag_writer.BagWriter` into ``folder/<name>`` and :meth:`add` returns its
path. A trigger while a capture is open extends nothing: the second event falls inside the
first bag.
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
        self._bufs: dict[str, deque[tuple[str, int, bytes]]] = {}
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
        q = self._bufs.setdefault(topic, deque())
        q.append((msgtype, t_ns, bytes(raw)))
        cap = self._capture
        if cap is not None:
            newest = [b[-1][1] for b in self._bufs.values() if b]
            stalled = max(newest) >= cap["end"] + self.pre_ns + self.post_ns + 1_000_000_000
            if min(newest) >= cap["end"] or stalled:
                return self._write()
            return None
        self._prune()
        return None

    def _prune(self) -> None:
        horizon = min(q[-1][1] for q in self._bufs.values() if q) - self.pre_ns
        for q in self._bufs.values():
            while q and q[0][1] < horizon:
                q.popleft()

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
        # heavy, optional: the rosbags writer, only when a capture is written (after a fault)
        from amb_tools.bag_writer import BagWriter

        cap = self._capture
        self._capture = None
        path = self.folder / cap["names"][0]
        k = 1
        while path.exists():
            path = self.folder / f"{cap['names'][0]}_{k}"
            k += 1
        lo, hi = cap["start"] - self.pre_ns, cap["end"]
        rows = sorted(
            (t_ns, topic, msgtype, raw)
            for topic, q in self._bufs.items()
            for msgtype, t_ns, raw in q
            if lo <= t_ns <= hi
        )
        with BagWriter(path, self.storage) as bag:
            for t_ns, topic, msgtype, raw in rows:
                bag.add_topic(topic, msgtype)
                bag.write_raw(topic, t_ns, raw)
        self.written.append(path)
        self._prune()  # keep the pre-trigger window for the next event
        return path
