"""
Trip levels with hysteresis on the displacement per sensor plane (e.g. 2/3 of the clearance).

A plane trips when its radial displacement ``hypot(x, y)`` exceeds ``level`` and clears when
it falls below ``level * (1 - hysteresis)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from amb_fault_monitor.errors import FaultMonitorError

__all__ = ["TripMonitor"]


class TripMonitor:
    """
    Displacement trip per plane with hysteresis.

    Parameters
    ----------
    level : float
        m, radial displacement trip level (0 disables).
    hysteresis : float
        Fraction in [0, 1) below ``level`` at which a trip clears.
    """

    def __init__(self, level: float, hysteresis: float = 0.1) -> None:
        if level < 0 or not 0 <= hysteresis < 1:
            raise FaultMonitorError(
                f"trip level must be >= 0 m and hysteresis in [0, 1), got {level}, {hysteresis}"
            )
        self.level = float(level)
        self.hysteresis = float(hysteresis)
        self.tripped = np.zeros(4, dtype=bool)
        self.peak = np.zeros(4)

    def reset(self) -> None:
        """Clear trips and peaks."""
        self.tripped[:] = False
        self.peak[:] = 0.0

    def step(self, displacement: ArrayLike) -> np.ndarray:
        """
        Update with one sample ``(8,)`` m; return the planes (0-based) that tripped now.
        """
        d = np.asarray(displacement, dtype=float)
        r = np.hypot(d[0::2], d[1::2])
        self.peak = np.maximum(self.peak, r)
        if self.level <= 0:
            return np.zeros(0, dtype=int)
        new = (r > self.level) & ~self.tripped
        self.tripped |= new
        self.tripped &= ~(r < self.level * (1.0 - self.hysteresis))
        return np.flatnonzero(new)
