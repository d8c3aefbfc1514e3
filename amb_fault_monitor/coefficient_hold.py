"""
Coefficient messages held until their samples' measurements are in (the fault monitor node).

A coefficient message whose last sample's measurement has not reached the monitor (another
writer, another path: no poll finds it) would be tested without that sample's control force:
a force kink in it unknown, a burst at it taken for a contact
(:mod:`amb_fault_monitor.control_transients`, "Kinks"). The node holds such messages, in
order, until the measurement is in (:meth:`CoefficientHold.release`), for at most
``capacity`` messages, and for at most ``timeout`` after the last measurement
(:meth:`CoefficientHold.expired`): a measurement stream that falls behind or stops does not
hold the monitor back longer. The messages given back so are counted (``unmatched``).
"""

from __future__ import annotations

from collections import deque
from typing import Any

__all__ = ["CoefficientHold"]


class CoefficientHold:
    """
    The held coefficient messages of one monitor node, oldest first.

    Parameters
    ----------
    capacity : int
        Messages held at most; the oldest beyond it are given back unmatched.
    timeout : float
        Seconds (of the ``now`` the caller passes) without a measurement after which every
        held message is given back unmatched.

    Attributes
    ----------
    unmatched : int
        Messages given back without their measurements.
    """

    def __init__(self, capacity: int, timeout: float) -> None:
        self.capacity = int(capacity)
        self.timeout = float(timeout)
        self.unmatched = 0
        self._held: deque[tuple[Any, ...]] = deque()
        self._moved = 0.0  # when the queue last moved: a message held into it empty, or a
        # measurement processed while messages were held

    def __bool__(self) -> bool:
        return bool(self._held)

    def wants(self, sample_index: int, last_sample: int | None) -> bool:
        """True if a message completed at ``sample_index`` must be held (order kept)."""
        return bool(self._held) or last_sample is None or sample_index > last_sample

    def hold(self, item: tuple, now: float) -> list[tuple]:
        """Hold ``item`` (its message first); return the oldest ones over ``capacity``."""
        if not self._held:
            self._moved = now
        self._held.append(item)
        return self._give_back(len(self._held) - self.capacity)

    def release(self, last_sample: int, now: float) -> list[tuple]:
        """The held items whose samples have all been measured (up to ``last_sample``)."""
        held = self._held
        if not held:
            return []
        self._moved = now  # the measurement stream is alive: late, not lost
        out = []
        while held and int(held[0][0].sample_index) <= last_sample:
            out.append(held.popleft())
        return out

    def expired(self, now: float) -> list[tuple]:
        """Every held item if no measurement came for ``timeout``, else none."""
        if self._held and now - self._moved > self.timeout:
            return self._give_back(len(self._held))
        return []

    def _give_back(self, count: int) -> list[tuple]:
        out = [self._held.popleft() for _ in range(max(count, 0))]
        self.unmatched += len(out)
        return out
