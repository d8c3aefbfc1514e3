"""
A lasting step of a bearing axis's mean force: the sign of a biased probe inside the PID loop.

The bearings' PID closes its loop on the inner probes beside the bearings (thesis section
2.6, eqs. 2.45-2.46), so it answers what those probes *say*. When one of them reads ``b`` off
(an offset, chapter 3's sensor faults), the loop answers a displacement that is not there: its
proportional part moves the rotor at that bearing until the magnet's negative stiffness
``K_z`` (eq. 2.39) balances the loop's ``K_p``, by ``K_p b / (K_z - K_p)``, several times
``b`` with a loop only just stiffer than the magnet; its integral part brings the reading back
to the set point over ``K_p / K_I`` (the rotor to ``-b``). Either way the bearing then holds
the rotor off its magnetic centre and the one-revolution mean of that axis's force steps to a
new, steady level (the suite's measurements: ``docs/fault_monitor_notes.md``, "Sensor faults
inside the PID loop"). The rotor's own faults do not do that: a sudden unbalance is
synchronous and averages out over a revolution, a contact is over within a few revolutions,
and a lost coil, which does step the force, is named by :mod:`amb_fault_monitor.coil_check`
first. The displacements alone cannot tell it: the loop spreads the probe's error over every
channel (the monitor's classifier rule 1 then finds no isolated channel).

:class:`LoopBias` averages the commanded force of each axis (``bearing_force`` of the
measurements, N) over whole revolutions. When the monitor has calibrated, the threshold per
axis is ``max(bias_floor, bias_factor * s)``, ``s`` the largest change of the mean from one
revolution to the next in the monitor's healthy window (:meth:`LoopBias.calibrate`).
:meth:`LoopBias.step_at` tells, at an episode's decision, the axis whose mean over the last
two revolutions has moved from its mean over the two revolutions before the episode by more
than its threshold, with the last two revolutions within ``bias_steady`` of each other
relative to that step (the new level is held, not a ring-down passing through).
"""

from __future__ import annotations

from collections import deque
from dataclasses import replace

import numpy as np

from amb_common.faults import FaultEvent, FaultType
from amb_common.names import AXIS_NAMES
from amb_fault_monitor.calibration import window_revolutions
from amb_fault_monitor.classifier import ratio_confidence

__all__ = ["LoopBias"]


class LoopBias:
    """
    One-revolution means of the commanded bearing force, and their steps.

    Parameters
    ----------
    config : MonitorConfig
        Or anything with its ``samples_per_rev``, ``calibration_revs``, ``decision_max_revs``,
        ``bias_floor``, ``bias_factor`` and ``bias_steady``.
    feedback_channels : sequence of int
        The sensor channel (0-based, ``[x1, y1, ..., x4, y4]``) each axis ``[b1x, b1y, b2x,
        b2y]`` is fed back from (:attr:`amb_common.rig.Rig.feedback_channels`).

    Attributes
    ----------
    threshold : numpy.ndarray or None
        Per axis ``[b1x, b1y, b2x, b2y]``, N (None while calibrating).
    channels : tuple of int
        ``feedback_channels``.
    """

    def __init__(self, config, feedback_channels) -> None:
        self.config = config
        self.channels = tuple(int(c) for c in feedback_channels)
        if len(self.channels) != 4:
            raise ValueError(f"feedback_channels: one per bearing axis (4), got {self.channels}")
        self.reset()

    def reset(self) -> None:
        """Forget the means and the calibration (a restart of the stream)."""
        cfg = self.config
        self.threshold: np.ndarray | None = None
        self._sum = np.zeros(4)
        self._count = 0
        self._block_start: int | None = None
        keep = int(cfg.decision_max_revs + cfg.calibration_revs) + 8
        self._means: deque[tuple[int, np.ndarray]] = deque(maxlen=keep)  # (first sample, mean)

    def add(self, n: int, commanded_force: np.ndarray) -> None:
        """
        Add one sample's commanded force (4,), N.

        A revolution's mean is kept once it has ``samples_per_rev`` samples; a gap in the
        sample indices starts the revolution afresh.
        """
        spr = self.config.samples_per_rev
        if self._block_start is None or n != self._block_start + self._count:
            self._sum[:] = 0.0
            self._count = 0
            self._block_start = n
        self._sum += commanded_force
        self._count += 1
        if self._count == spr:
            self._means.append((self._block_start, self._sum / spr))
            self._sum = np.zeros(4)
            self._count = 0
            self._block_start = n + 1

    def calibrate(self, end: int) -> None:
        """
        Set the thresholds from the revolutions of the monitor's healthy window.

        Parameters
        ----------
        end : int
            The sample at which the monitor's thresholds were set: the window is the
            ``calibration_revs`` revolutions before it. Fewer than two revolutions' means in
            it (no currents fed) leave the check off.
        """
        cfg = self.config
        means = window_revolutions(self._means, end, cfg)
        if len(means) < 2:
            return
        steps = np.abs(np.diff(np.array(means), axis=0)).max(axis=0)
        self.threshold = np.maximum(cfg.bias_floor, cfg.bias_factor * steps)

    def step_at(self, start: int) -> tuple[int, np.ndarray] | None:
        """
        The axis whose mean force has stepped since before sample ``start``, or None.

        Parameters
        ----------
        start : int
            The episode's first sample (its first crossing).

        Returns
        -------
        tuple or None
            ``(axis, step)``: the axis (0..3, ``[b1x, b1y, b2x, b2y]``) with the largest step
            over its threshold and the steps of all four axes (4,), N; None when no axis has
            a steady step above its threshold, when the means do not reach two revolutions
            back before the episode, or when fewer than four whole revolutions follow its
            start (the last two of them are compared, after the first transient).
        """
        if self.threshold is None:
            return None
        before = [m for first, m in self._means if first + self.config.samples_per_rev <= start]
        after = [m for first, m in self._means if first >= start]
        if len(before) < 2 or len(after) < 4:
            return None
        reference = (before[-1] + before[-2]) / 2
        last, previous = after[-1], after[-2]
        step = (last + previous) / 2 - reference
        ratio = np.abs(step) / self.threshold
        axis = int(np.argmax(ratio))
        if ratio[axis] < 1.0:
            return None
        if abs(last[axis] - previous[axis]) > self.config.bias_steady * abs(step[axis]):
            return None
        return axis, step

    def revise(self, ev: FaultEvent, start: int, mask: np.ndarray) -> FaultEvent:
        """
        The decision of an episode, revised: a contact may be a biased feedback probe.

        Parameters
        ----------
        ev : FaultEvent
            The classifier's decision of an episode that began at sample ``start``.
        start : int
            The episode's first sample.
        mask : numpy.ndarray
            Channels in use (8,), bool: a probe already masked is not reported again.

        Returns
        -------
        FaultEvent
            ``ev``, or, when it is an ``AUX_BEARING_CONTACT`` and an axis's mean force has a
            held step (:meth:`step_at`), the ``SENSOR_FAULT`` of that axis's feedback probe
            with the same onset, detection and decision samples.
        """
        if ev.fault_type != FaultType.AUX_BEARING_CONTACT:
            return ev
        found = self.step_at(start)
        if found is None:
            return ev
        axis, step = found
        channel = self.channels[axis]
        if not mask[channel]:
            return ev
        plane = channel // 2 + 1
        threshold = float(self.threshold[axis])
        name = AXIS_NAMES[axis]
        return replace(
            ev,
            fault_type=FaultType.SENSOR_FAULT,
            plane=plane,
            channel=channel,
            bearing=0,
            severity=abs(float(step[axis])),
            confidence=ratio_confidence(abs(step[axis]) / threshold),
            count=1,
            evidence={
                **ev.evidence,
                "rule": "a bearing axis's mean force stepped to a new held level: the probe the "
                "PID holds it on reads off",
                "displacement_class": ev.fault_type.name,
                "force_axis": name,
                "mean_force_step_n": [float(v) for v in step],
                "force_threshold_n": threshold,
            },
            description=(
                f"the mean force of {name} stepped by {float(step[axis]):.3g} N and holds "
                f"(threshold {threshold:.3g} N): probe plane {plane} {'xy'[channel % 2]} "
                f"(channel {channel}), inside the PID loop, reads off; the rotor moved with it "
                f"(its displacements alone read {ev.fault_type.name})"
            ),
        )
