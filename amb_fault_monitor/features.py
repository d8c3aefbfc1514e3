r"""
Detection features: the change of each completed detail coefficient (thesis chapter 5).

Per completed detail coefficient, per level ``j``, frame and sensor plane ``p``, coefficients
are first normalised to metres, ``c = d / 2**(j / 2)`` (the orthonormal filters of eq. 4.6
scale a level-``j`` coefficient by the square root of its support). The feature is the change
of the coefficient (figure 5.30 c-d: "the change in wavelet coefficients with each sample"),
taken between coefficients one revolution apart where a level has several coefficients per
revolution:

.. math::

    \Delta_j[k] = c_j[k] - c_j[k - m_j], \quad
    m_j = \max(1, 2^{R - j}), \qquad
    e_{j,p}[k] = \sqrt{\Delta_{j,x_p}^2 + \Delta_{j,y_p}^2},

with ``R = log2(samples_per_rev)`` (level ``R`` is 1 x running speed). Decision (a
generalisation of the thesis): for ``j < R`` the thesis's coefficient-to-coefficient change
is periodic, not zero, under a steady orbit in the fixed frame (eq. 5.3-5.4 only make the
*rotating*-frame coefficients vanish); the one-revolution lag makes ``Delta`` vanish for any
steady response periodic in the revolution, in both frames (the steady orbit, its harmonics,
and the rotating-frame image of static offsets such as gravity sag), so that only transients
remain, as eq. 5.4 requires. At ``j = R`` and coarser, ``m_j = 1`` is the thesis's change
from one coefficient to the next.

Thresholds ``theta_{j,f,p}`` come from a healthy calibration window
(:mod:`amb_fault_monitor.calibration`); the ratio ``r = e / theta`` crosses when ``r > 1``.
Channels found faulty are left out (``mask``): in the rotating frame both channels of the
plane, since u and v each mix x and y.
"""

from __future__ import annotations

import numpy as np

from amb_common.names import N_SENSORS

__all__ = ["ChangeFeatures", "frame_mask", "normalise"]


def normalise(level: int, values) -> np.ndarray:
    """Coefficients of ``level`` in metres: ``d / 2**(level / 2)`` (the filters of eq. 4.6)."""
    return np.asarray(values, dtype=float) / 2.0 ** (level / 2)


def frame_mask(mask: np.ndarray, frame: str) -> np.ndarray:
    """Channels in use (8,) in ``frame``: in the rotating frame u and v both mix x and y."""
    if frame == "fixed":
        return mask
    return np.repeat(mask[0::2] & mask[1::2], 2)


class _FrameMasks:
    """:func:`frame_mask` of the last mask seen (masks change once per channel found faulty)."""

    def __init__(self) -> None:
        self._key: bytes | None = None
        self._rotating = np.ones(N_SENSORS, dtype=bool)

    def get(self, mask: np.ndarray, frame: str) -> np.ndarray:
        if frame == "fixed":
            return mask
        key = mask.tobytes()
        if key != self._key:
            self._key, self._rotating = key, frame_mask(mask, frame)
        return self._rotating


class _Lag:
    """Ring buffer of the last ``m`` coefficient vectors of one (level, frame)."""

    def __init__(self, m: int) -> None:
        self.buf = np.zeros((m, N_SENSORS))
        self.m = m
        self.pos = 0
        self.count = 0

    def push(self, v: np.ndarray) -> np.ndarray | None:
        """Store ``v``; return ``v`` minus the vector ``m`` pushes ago (None until there is one)."""
        change = v - self.buf[self.pos] if self.count >= self.m else None
        self.buf[self.pos] = v
        self.pos = (self.pos + 1) % self.m
        self.count += 1
        return change


class ChangeFeatures:
    """
    The lagged change ``Delta_j`` of each (level, frame), coefficient by coefficient.

    Parameters
    ----------
    revolution_level : int
        ``R``, the level of 1 x running speed.
    """

    def __init__(self, revolution_level: int) -> None:
        self._R = revolution_level
        self._lags: dict[tuple[int, str], _Lag] = {}
        self._masks = _FrameMasks()

    def change(self, level: int, frame: str, values, mask: np.ndarray) -> np.ndarray | None:
        """
        ``Delta`` (8,) of the newest coefficients of (``level``, ``frame``), m.

        ``values`` are the raw coefficients (8,); channels outside ``mask`` (:func:`frame_mask`)
        are zero. None until ``m_j`` coefficients were received.
        """
        key = (level, frame)
        lag = self._lags.get(key)
        if lag is None:
            lag = self._lags[key] = _Lag(max(1, 2 ** (self._R - level)))
        change = lag.push(normalise(level, values))
        if change is None:
            return None
        return change * self._masks.get(mask, frame)
