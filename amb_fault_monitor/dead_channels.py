"""
Stuck or zero sensor channels (thesis chapter 3: a constant signal of one transducer).

A constant signal has zero detail coefficients at every level. A channel whose finest-level
(fixed-frame) coefficient stays below ``dead_fraction`` of its healthy median for
``dead_revs`` revolutions is reported as stuck or zero (``SENSOR_FAULT``), and the monitor
masks it from then on (its plane feature uses the partner channel only) until its reset.
"""

from __future__ import annotations

import math

import numpy as np

from amb_common.faults import FaultEvent, FaultType
from amb_common.names import N_SENSORS

__all__ = ["DeadChannels"]


class DeadChannels:
    """
    The stuck/zero test of each channel against its healthy finest-level median.

    Parameters
    ----------
    config : MonitorConfig
        Or anything with its ``samples_per_rev``, ``dead_fraction`` and ``dead_revs``.

    Attributes
    ----------
    reference : numpy.ndarray or None
        Healthy median magnitude (8,) of each channel's finest-level coefficient, m (set from
        the calibration; None: no test).
    """

    def __init__(self, config) -> None:
        self.config = config
        self._run = np.zeros(N_SENSORS, dtype=int)
        self._running = False  # whether a run may be non-zero
        self.reference = None

    @property
    def reference(self) -> np.ndarray | None:
        """Healthy median magnitude (8,) per channel, m, or None (class docstring)."""
        return self._reference

    @reference.setter
    def reference(self, value: np.ndarray | None) -> None:
        self._reference = value
        # the "low" limit per channel; a channel without a healthy level (0) is never low
        self._low = None if value is None else np.where(value > 0, value, -np.inf)

    def check(
        self, n: int, magnitudes: np.ndarray, mask: np.ndarray, omega: float
    ) -> list[tuple[FaultEvent, int]]:
        """
        Test the finest-level magnitudes (8,) completed at sample ``n``, m.

        Parameters
        ----------
        n : int
            Sample index.
        magnitudes : numpy.ndarray
            ``|c|`` per channel (normalised, m).
        mask : numpy.ndarray
            Channels in use (8,), bool: only those are tested.
        omega : float
            Running speed for the events, rad/s.

        Returns
        -------
        list of (FaultEvent, int)
            A ``SENSOR_FAULT`` per channel found stuck now, with the first sample of its low
            run. The caller masks the channel.
        """
        ref = self._reference
        if ref is None:
            return []
        cfg = self.config
        v = magnitudes
        low = (v < cfg.dead_fraction * self._low) & mask
        if not (self._running or np.count_nonzero(low)):
            return []  # the usual coefficient: no channel low, no run to end
        self._run = np.where(low, self._run + 1, 0)
        self._running = bool(np.count_nonzero(self._run))
        need = max(2, math.ceil(cfg.dead_revs * cfg.samples_per_rev / 2))
        found = []
        for ch in np.flatnonzero(self._run >= need):
            start = n - 2 * int(self._run[ch])
            self._run[ch] = 0
            ev = FaultEvent(
                FaultType.SENSOR_FAULT,
                onset_sample_index=max(start, 0),
                detection_sample_index=n,
                decision_sample_index=n,
                samples_per_rev=cfg.samples_per_rev,
                omega=omega,
                plane=int(ch) // 2 + 1,
                channel=int(ch),
                severity=float(ref[ch]),
                confidence=float(1.0 - v[ch] / max(cfg.dead_fraction * ref[ch], 1e-300)),
                evidence={
                    "mode": "stuck_or_zero",
                    "level": 1,
                    "frame": "fixed",
                    "healthy_median_m": float(ref[ch]),
                    "now_m": float(v[ch]),
                },
                description=(
                    f"sensor channel {ch} stuck or zero: finest-level coefficient below "
                    f"{cfg.dead_fraction:g} x its healthy median for {cfg.dead_revs:g} rev"
                ),
            )
            ev.confidence = float(min(max(ev.confidence, 0.0), 1.0))
            found.append((ev, start))
        return found
