r"""
Thresholds calibrated automatically from a healthy window (robust statistics).

Every detection feature (a non-negative magnitude, one per level, frame and sensor plane) is
collected over the calibration window and its threshold set to

.. math::

    \theta = \max\left(\operatorname{median}(c) + k \cdot 1.4826
    \operatorname{MAD}(c),\; \theta_{\min}\right),

where MAD is the median absolute deviation from the median and ``1.4826`` makes
``1.4826 MAD`` equal to the standard deviation for Gaussian data. Median and MAD ignore up to
half the window being outliers, so a short disturbance inside the calibration window does not
inflate the threshold the way a mean and standard deviation would.

Choice of ``k`` (documented, not tuned per scenario): the plane features are magnitudes of two
(nearly) Gaussian components, i.e. Rayleigh distributed with scale ``s``; then
``median = 1.177 s`` and ``1.4826 MAD = 0.664 s``, so ``k = 8`` puts the threshold at
``6.5 s``, exceeded with probability ``exp(-6.5**2 / 2) = 7e-10`` per coefficient: below one
false crossing in 10 simulated minutes at 67 Hz with 32 samples/rev, 6 levels, 2 frames and
4 planes (``about 1e8`` tests). Crossings must further be confirmed (see
:mod:`amb_fault_monitor.monitor`). The floor ``theta_min`` (m) covers noise-free
signals, where MAD is 0 and any round-off would otherwise cross.

:class:`CalibrationWindow` collects the healthy features of the monitor (per level and frame,
the synchronous phasor change, the finest-level magnitudes of the stuck-channel test) and sets
the thresholds once its window is full and stationary.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from amb_fault_monitor.errors import FaultMonitorError

__all__ = [
    "MAD_TO_SIGMA", "Calibration", "CalibrationWindow", "median", "robust_threshold",
    "window_revolutions",
]  # fmt: skip

MAD_TO_SIGMA = 1.4826


def median(a: ArrayLike, axis: int | None = None) -> np.ndarray | float:
    """
    ``numpy.median`` of finite values, by one sort: the middle value, or the mean of the two.

    The same numbers as ``numpy.median`` (it averages the same two middle values), without
    its per-call overhead (tens of us): a calibration attempt takes about ninety medians of
    short arrays, once per revolution, on the monitor's thread (7 ms at 67 Hz x 32 with
    ``numpy.median``, a whole control period in the composed stack).

    Parameters
    ----------
    a : array_like
        Finite values (a NaN would sort last instead of propagating).
    axis : int or None
        0: along the first axis; None: over every value.

    Returns
    -------
    numpy.ndarray or float
    """
    s = np.sort(np.asarray(a, dtype=float), axis=axis)
    if axis is None:
        s = s.ravel()
    elif axis != 0:
        raise ValueError(f"axis = {axis}: 0 or None")
    n = s.shape[0]
    if n == 0:
        raise ValueError("median of an empty array")
    return (s[(n - 1) // 2] + s[n // 2]) / 2


def window_revolutions(kept, end: int, config) -> list:
    """
    The per-revolution values whose revolution lies in the calibration window ending at ``end``.

    Parameters
    ----------
    kept : iterable of (int, object)
        ``(first sample of the revolution, its value)``.
    end : int
        The sample at which the monitor's thresholds were set: the window is the
        ``calibration_revs`` revolutions before it.
    config : MonitorConfig
        Or anything with ``samples_per_rev`` and ``calibration_revs``.
    """
    spr = config.samples_per_rev
    first = end - config.calibration_revs * spr
    return [value for start, value in kept if start >= first and start + spr <= end + 1]


def robust_threshold(samples: ArrayLike, k: float, floor: float, axis: int = 0) -> np.ndarray:
    """
    Threshold ``max(median + k * 1.4826 * MAD, floor)`` along ``axis``.

    Parameters
    ----------
    samples : array_like
        Healthy values of the feature(s), e.g. shape ``(N, 4)`` for 4 planes (m).
    k : float
        Number of robust standard deviations above the median (> 0).
    floor : float
        Smallest threshold (same unit as ``samples``, >= 0).
    axis : int
        Axis holding the observations.

    Returns
    -------
    numpy.ndarray
        Threshold per remaining index.

    Raises
    ------
    FaultMonitorError
        If there are fewer than 8 observations, ``k <= 0`` or ``floor < 0``.
    """
    a = np.asarray(samples, dtype=float)
    if a.ndim == 0 or a.shape[axis] < 8:
        raise FaultMonitorError(
            f"calibration needs >= 8 healthy observations per feature, got shape {a.shape}; "
            "lengthen the calibration window"
        )
    if not k > 0:
        raise FaultMonitorError(f"k must be > 0, got {k}")
    if not floor >= 0:
        raise FaultMonitorError(f"floor must be >= 0, got {floor}")
    if axis != 0:
        a = np.moveaxis(a, axis, 0)
    med = median(a, axis=0)
    mad = median(np.abs(a - med), axis=0)
    return np.maximum(med + k * MAD_TO_SIGMA * mad, floor)


@dataclass(frozen=True)
class Calibration:
    """
    The outcome of a healthy calibration window.

    Attributes
    ----------
    thresholds : dict
        Per (level, frame): plane thresholds (4,), m.
    sync_threshold : numpy.ndarray
        Per plane threshold of the synchronous phasor change (4,), m.
    dead_reference : numpy.ndarray or None
        Per channel median of the finest-level coefficient magnitude (8,), m; None when no
        finest level was received.
    end : int
        Sample index at which the window was accepted.
    """

    thresholds: dict[tuple[int, str], np.ndarray]
    sync_threshold: np.ndarray
    dead_reference: np.ndarray | None
    end: int


class CalibrationWindow:
    """
    The sliding healthy window over which the monitor's thresholds are calibrated.

    The window holds the last ``calibration_revs`` revolutions. It is accepted when, for
    every (level, frame) and for the synchronous phasor change, the median of the first half
    (planes pooled) is at most ``settle_ratio`` times the median of the second half: a
    start-up or run-up transient that still decays fails the test, and the window slides on
    (the rotor may be started, or the monitor restarted, in a transient, and thresholds
    calibrated on it would be far above the noise-only ones). The window is refused too while
    a feature of its last revolution exceeds the thresholds it gives: a disturbance that began
    in the window's last revolutions moves neither half's median, and would then be reported
    once calibrated, with an onset at the calibration's end. The test runs once per
    revolution.

    Parameters
    ----------
    config : MonitorConfig
        Or anything with its ``samples_per_rev``, ``calibration_revs``, ``settle_ratio``,
        ``k`` and ``threshold_floor``.

    Attributes
    ----------
    retries : int
        Times the window was refused (still settling, or disturbed in its last revolution).
    """

    def __init__(self, config) -> None:
        self.config = config
        self.retries = 0
        self._features: dict[tuple[int, str], deque] = {}
        self._sync: deque = deque()
        self._dead: deque = deque()
        self._start: int | None = None
        self._tried = -(2**62)

    def add_sync(self, n: int, planes: np.ndarray) -> None:
        """Collect a healthy change (4,) of the synchronous phasor completed at sample ``n``."""
        self._sync.append((n, planes))

    def add_dead(self, n: int, magnitudes: np.ndarray) -> None:
        """Collect healthy finest-level magnitudes (8,) completed at sample ``n``."""
        self._dead.append((n, magnitudes))

    def add_feature(self, n: int, key: tuple[int, str], planes: np.ndarray) -> Calibration | None:
        """
        Collect a healthy plane feature (4,) of ``key`` = (level, frame) completed at ``n``.

        Returns
        -------
        Calibration or None
            The thresholds once the window is full, stationary and undisturbed; None before.
        """
        cfg = self.config
        spr = cfg.samples_per_rev
        if self._start is None:
            self._start = n
        self._features.setdefault(key, deque()).append((n, planes))
        window = cfg.calibration_revs * spr
        if n - self._start < window or n - self._tried < spr:
            return None
        self._tried = n
        lo = n - window
        for q in (*self._features.values(), self._sync, self._dead):
            while q and q[0][0] <= lo:
                q.popleft()
        if any(len(v) < 8 for v in self._features.values()) or len(self._sync) < 8:
            return None  # coarse levels (few coefficients per revolution) still filling
        mid = n - window / 2
        for q in (*self._features.values(), self._sync):
            first = [v for m, v in q if m <= mid]
            second = [v for m, v in q if m > mid]
            if not first or not second:
                return None
            if median(first) > cfg.settle_ratio * max(median(second), cfg.threshold_floor):
                self.retries += 1
                return None  # still settling
        thr = {k: self._plane_thresholds(q) for k, q in self._features.items()}
        last = n - spr
        if any(m > last and np.any(v > thr[k]) for k, q in self._features.items() for m, v in q):
            self.retries += 1
            return None  # a disturbance in the window's last revolution: not healthy yet
        sync = robust_threshold(np.array([v for _m, v in self._sync]), cfg.k, cfg.threshold_floor)
        dead = None
        if self._dead:
            dead = median(np.abs(np.array([v for _m, v in self._dead])), axis=0)
        self._features.clear()
        return Calibration(thr, sync, dead, n)

    def _plane_thresholds(self, q: deque) -> np.ndarray:
        """
        Plane thresholds: the larger of the per-plane and the planes-pooled robust threshold.

        Coarse levels give few coefficients per window (one per two revolutions at the level
        below 1 x: 8 in 16 revolutions); the MAD of 8 values is too uncertain. Pooling the
        four planes (sensor noise is common to the probes) gives 4 times the observations;
        the per-plane value is kept where a plane moves more.
        """
        cfg = self.config
        a = np.array([v for _m, v in q])
        per_plane = robust_threshold(a, cfg.k, cfg.threshold_floor)
        pooled = robust_threshold(a.ravel(), cfg.k, cfg.threshold_floor)
        return np.maximum(per_plane, pooled)
