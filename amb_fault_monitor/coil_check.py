"""
Coil and amplifier failures (thesis chapter 3: loss of an AMB coil or amplifier channel).

Each bearing axis is driven by two opposing coils carrying ``I_b + i`` and ``I_b - i``
(eq. 2.33); the current sensors give the control current as half their difference, which
equals the demand ``i`` while both coils carry what they are asked to. A lost channel breaks
that: with both coils dead the axis reads 0 whatever the demand, with one coil left it reads
``(I_b + i) / 2`` or ``(i - I_b) / 2``, a step of ``I_b / 2`` (2.35 A on the thesis's rig).
The check compares, per axis and sample, the demanded current (the measurement's commanded
force over ``K_i``) with the measured one: a difference above the axis's threshold for
``coil_confirm_revs`` revolutions is a ``COIL_FAILURE`` of that axis, reported once (until
:meth:`CoilCheck.reset`). The rotor's displacements play no part, so a mass loss, a contact or
a sensor fault cannot raise it, and it comes a quarter revolution after the failure, before the
rotor has moved far.

The threshold is ``max(coil_floor, coil_factor * d_max)`` with ``d_max`` the largest
difference of the axis over the first ``calibration_revs`` revolutions (an amplifier with its
own dynamics lags its demand: ``amplifier: coil`` in ``config/rig.yaml``), so that only a
difference several times what the healthy amplifier shows counts.
"""

from __future__ import annotations

import math

import numpy as np

from amb_common.faults import FaultEvent, FaultType
from amb_common.names import AXIS_NAMES
from amb_fault_monitor.classifier import ratio_confidence

__all__ = ["CoilCheck"]


class CoilCheck:
    """
    Demanded against measured control current per bearing axis.

    Parameters
    ----------
    config : MonitorConfig
        Or anything with its ``samples_per_rev``, ``calibration_revs``, ``coil_floor``,
        ``coil_factor`` and ``coil_confirm_revs``.
    ki : float
        Current gain ``K_i`` of the rig, N/A (the commanded force over it is the demand).

    Attributes
    ----------
    threshold : numpy.ndarray or None
        Per axis, A (None while calibrating).
    failed : numpy.ndarray
        Axes already reported (4,), bool.
    """

    def __init__(self, config, ki: float) -> None:
        if not ki > 0:
            raise ValueError(f"ki = {ki}: the current gain must be > 0 N/A")
        self.config = config
        self.ki = float(ki)
        self.reset()

    def reset(self) -> None:
        """Forget the calibration and the failures (a restart of the stream)."""
        self.threshold: np.ndarray | None = None
        self._limits: list[float] = []  # the threshold as floats (the per-sample test)
        self._running = False  # whether a run may be non-zero
        self.failed = np.zeros(4, dtype=bool)
        self._seen = 0
        self._largest = np.zeros(4)
        self._run = np.zeros(4, dtype=int)
        self._first = np.zeros(4, dtype=np.int64)

    @property
    def _window(self) -> int:
        return max(1, round(self.config.calibration_revs * self.config.samples_per_rev))

    @property
    def _confirm(self) -> int:
        return max(1, math.ceil(self.config.coil_confirm_revs * self.config.samples_per_rev))

    def step(
        self, n: int, commanded_force: np.ndarray, current: np.ndarray, omega: float
    ) -> list[FaultEvent]:
        """
        Check one sample.

        Parameters
        ----------
        n : int
            Sample index.
        commanded_force : numpy.ndarray
            ``bearing_force`` of the measurement (4,), N: ``K_i`` times the demanded current.
        current : numpy.ndarray
            Measured control current (4,), A.
        omega : float
            Running speed, rad/s (for the event).

        Returns
        -------
        list of FaultEvent
            A ``COIL_FAILURE`` for each axis confirmed at this sample (usually none).
        """
        ki = self.ki
        # four values: plain floats, each numpy call would cost more than the arithmetic
        listed = [
            abs(f / ki - i)
            for f, i in zip(
                np.asarray(commanded_force, float).tolist(),
                np.asarray(current, float).tolist(),
                strict=True,
            )
        ]
        if self.threshold is None:
            self._largest = np.maximum(self._largest, listed)
            self._seen += 1
            if self._seen >= self._window:
                cfg = self.config
                self.threshold = np.maximum(cfg.coil_floor, cfg.coil_factor * self._largest)
                self._limits = self.threshold.tolist()
            return []
        if not any(d > t for d, t in zip(listed, self._limits, strict=True)):
            # the usual sample: every run ends, nothing confirmed
            if self._running:
                self._run[:] = 0
                self._running = False
            return []
        diff = np.array(listed)
        over = diff > self.threshold
        over &= ~self.failed
        self._first = np.where(over & (self._run == 0), n, self._first)
        self._run = np.where(over, self._run + 1, 0)
        self._running = True
        events = []
        for axis in np.flatnonzero(self._run >= self._confirm):
            self.failed[axis] = True
            self._run[axis] = 0
            name = AXIS_NAMES[axis]
            bearing = int(axis) // 2 + 1
            ratio = float(diff[axis] / self.threshold[axis])
            demanded = float(commanded_force[axis]) / self.ki
            events.append(
                FaultEvent(
                    FaultType.COIL_FAILURE,
                    int(self._first[axis]),
                    int(n),
                    int(n),
                    self.config.samples_per_rev,
                    float(omega),
                    plane=0,
                    bearing=bearing,
                    severity=0.0,
                    confidence=ratio_confidence(ratio),
                    evidence={
                        "axis": name,
                        "demanded_a": demanded,
                        "measured_a": float(current[axis]),
                        "difference_a": float(diff[axis]),
                        "threshold_a": float(self.threshold[axis]),
                        "rule": "measured control current departs from the demand",
                    },
                    description=(
                        f"AMB {bearing} axis {name}: measured control current "
                        f"{float(current[axis]):.3g} A against {demanded:.3g} A demanded, "
                        f"apart for {self._confirm} samples (threshold "
                        f"{float(self.threshold[axis]):.3g} A): coil or amplifier failure"
                    ),
                )
            )
        return events
