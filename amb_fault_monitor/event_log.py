"""
Event log that survives restarts: JSON lines, one event per line, reloaded at start.

Each line is :meth:`FaultEvent.to_dict` plus ``time`` (s, detection stamp). The log keeps the
touchdown (contact) counter per clearance bearing (1, 2 = auxiliary bearings in AMB 1, 2;
3, 4 = retainers at planes 1, 4; 0 = not located) and assigns increasing ``event_id``.
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

from amb_common.faults import FaultEvent, FaultType
from amb_fault_monitor.errors import FaultMonitorError

__all__ = ["EventLog"]


class EventLog:
    """
    Append-only JSON-lines event log.

    Parameters
    ----------
    path : str or Path or None
        File; created if missing, reloaded if present. ``None`` keeps the log in memory.

    Raises
    ------
    FaultMonitorError
        If an existing file has a line that is not a logged event (the line number is given;
        move the file away to start a new log).
    """

    def __init__(self, path: str | Path | None) -> None:
        self.path = Path(path) if path else None
        self.events: list[dict] = []
        self.contacts: Counter[int] = Counter()
        self._next_id = 1
        if self.path is not None and self.path.exists():
            for i, line in enumerate(self.path.read_text(encoding="utf-8").splitlines(), 1):
                if not line.strip():
                    continue
                try:
                    d = json.loads(line)
                    FaultType[d["fault_type"]]
                except (ValueError, KeyError) as exc:
                    raise FaultMonitorError(
                        f"{self.path}:{i} is not a fault event ({exc}); move the file away"
                    ) from exc
                self._count(d)

    def _count(self, d: dict) -> None:
        self.events.append(d)
        self._next_id = max(self._next_id, int(d.get("event_id", 0)) + 1)
        if d["fault_type"] == FaultType.AUX_BEARING_CONTACT.name:
            self.contacts[int(d.get("bearing", 0))] += int(d.get("count", 1))

    def append(self, event: FaultEvent, time: float) -> FaultEvent:
        """Number ``event``, write it (flushed) and update the counters; return it."""
        event.event_id = self._next_id
        d = event.to_dict()
        d["time"] = float(time)
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            with self.path.open("a", encoding="utf-8") as fh:
                fh.write(json.dumps(d, default=float) + "\n")
        self._count(d)
        return event
