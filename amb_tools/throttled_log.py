"""
Warnings at most once per period and reason, decided before rclpy's logger is called.

rclpy's ``logger.warning(text, throttle_duration_sec=T)`` keys its throttle on the caller and
finds the caller with :mod:`inspect` (source file, ``realpath``, ``lstat`` of each path part)
on every call, suppressed or not: hundreds of microseconds a call (``bench/throttled_log.py``
measures both). A node that warns once per discontinuous sample pays that per sample exactly
when it is already behind, and the backlog grows from the warnings themselves. Here the
decision is a dictionary look-up and a clock read; the rclpy logger is called only for the
warnings that are printed, and each printed one says how many like it were held back, so
nothing is hidden (the counts on ``/diagnostics`` stay exact either way).
"""

from __future__ import annotations

import time
from typing import Any

__all__ = ["ThrottledWarnings"]


class ThrottledWarnings:
    """
    At most one warning per ``period`` seconds for each key, on a node's logger.

    Parameters
    ----------
    logger : rclpy logger
        Where the printed warnings go (``node.get_logger()``).
    period : float
        Minimum wall time between two printed warnings of one key, s.
    clock : callable, optional
        Monotonic time in s (tests pass their own).
    """

    def __init__(self, logger: Any, period: float, clock=time.monotonic) -> None:
        if not period >= 0.0:
            raise ValueError(f"period = {period!r}: must be >= 0 s")
        self._logger = logger
        self._period = float(period)
        self._clock = clock
        self._printed: dict[str, float] = {}
        self._held: dict[str, int] = {}

    def warning(self, key: str, text: str) -> bool:
        """
        Print ``text`` unless a warning of ``key`` was printed less than ``period`` s ago.

        Parameters
        ----------
        key : str
            What kind of warning this is (a counter's name, a call site); texts differ per
            sample, keys do not.
        text : str
            The warning.

        Returns
        -------
        bool
            Whether it was printed. A printed warning ends with the number of warnings of the
            same key held back since the last printed one, if any.
        """
        now = self._clock()
        last = self._printed.get(key)
        if last is not None and now - last < self._period:
            self._held[key] = self._held.get(key, 0) + 1
            return False
        held = self._held.pop(key, 0)
        self._printed[key] = now
        if held:
            text += f" ({held} more like it in the last {now - last:.1f} s)"
        self._logger.warning(text)
        return True

    def held(self, key: str) -> int:
        """Warnings of ``key`` held back since the last printed one."""
        return self._held.get(key, 0)
