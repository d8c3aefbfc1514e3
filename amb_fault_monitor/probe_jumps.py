"""
Jumps of one probe's reading: the signature of a sensor offset, from its first sample.

A rotor's position is continuous, and so is its velocity except at an impact: every force a
rotor fault brings (an unbalance, a contact, a lost coil) changes the acceleration, or at
most the velocity, of the shaft. A probe that starts reading ``b`` off (an offset, chapter 3's
sensor faults) makes its reading *jump* by ``b`` between two samples while the slope before
and after stays what it was, and no other probe jumps with it (the mode shapes move
neighbouring probes together). That holds inside the PID loop too: the loop answers the
false reading a sample later with a force, which the rotor's mass filters, so the jump is
over before the loop has spread the fault over every channel (what defeats rule 1 of
:mod:`amb_fault_monitor.classifier` on the probes of planes 2 and 3; the held force step of
:mod:`amb_fault_monitor.loop_bias` tells it four revolutions later).

Per channel, with ``x`` the samples of one probe (m), the reading of sample ``n - 1`` against
the straight lines through its neighbours on either side,

    s[n] = (3 x[n-1] - 3 x[n-2] + x[n-3] - x[n]) / 2,
    l[n] = x[n] - x[n-1] - x[n-2] + x[n-3],

``s`` the *jump* (minus half the third difference) and ``l`` the change of slope (the first
difference after minus the one before, times the sample period ``T``). A step of ``b`` at
sample ``n0`` gives ``s[n0 + 1] = b``, ``l[n0 + 1] = 0`` and ``|s| = b / 2`` with ``|l| = b``
on the samples either side; a velocity change ``dv`` (an impact) between two samples gives
``|l| = dv T`` and ``|s| <= dv T / 2``; a smooth signal of amplitude ``A`` at ``k`` samples
per cycle gives ``|s| <= A (2 pi / k)**3 / 2`` and ``l`` its curvature, ``2 A (2 pi / k)**2``
(7.7 um for 100 um at 32 samples per cycle: as large as a small offset), which the *lasting*
change ``l[n] - l[n-4]`` (against the change of slope just before the four samples of ``s``)
leaves out up to ``4 A (2 pi / k)**3``. A sample is a *jump* of channel ``c`` when

* ``|s_c| >= jump_factor`` times the channel's threshold, the largest ``|s_c|`` of the
  monitor's healthy calibration window (set by the probe noise on the suite: ``s`` of white
  noise has 2.24 times its standard deviation);
* every other channel's ``|s| / threshold`` is at most ``jump_isolation`` times channel ``c``'s;
* ``|l_c[n] - l_c[n-4]| <= jump_lasting * |s_c|`` (not an impact's change of slope).

Of two jumps of one channel on adjacent samples the larger is kept. Inside the PID loop the
loop's answer to the false reading moves the rotor within the next sample (most at low speed,
where a sample is longest), so the lasting change of an offset is not zero there.

The monitor names the probe in an episode's provisional class when its channel alone jumped
within a quarter revolution of the episode's estimated onset
(:mod:`amb_fault_monitor.provisional`); what the suites gave is in
``docs/fault_monitor_notes.md``, "Jumps of one probe".
"""

from __future__ import annotations

from collections import deque

import numpy as np

from amb_common.faults import FaultType
from amb_common.names import N_SENSORS
from amb_fault_monitor.calibration import window_revolutions
from amb_fault_monitor.classifier import Decision, ratio_confidence

__all__ = ["Jump", "ProbeJumps", "jump_decision"]

#: (sample of the jump, channel 0-based, jump over the channel's threshold, jump in m)
Jump = tuple[int, int, float, float]


class ProbeJumps:
    """
    Streaming jump test of the probe readings (module docstring).

    Parameters
    ----------
    config : MonitorConfig
        Or anything with its ``samples_per_rev``, ``calibration_revs``, ``decision_max_revs``,
        ``threshold_floor``, ``jump_factor``, ``jump_isolation`` and ``jump_lasting``.

    Attributes
    ----------
    threshold : numpy.ndarray or None
        Per channel (8,), m: the largest healthy ``|s|`` (None while calibrating).
    jumps : collections.deque of Jump
        The jumps found since the calibration, the latest ``decision_max_revs`` revolutions'
        worth at most.
    """

    def __init__(self, config) -> None:
        self.config = config
        self.reset()

    def reset(self) -> None:
        """Forget the samples, the jumps and the calibration (a restart of the stream)."""
        cfg = self.config
        self.threshold: np.ndarray | None = None
        self._x: deque[np.ndarray] = deque(maxlen=8)
        self._last: int | None = None
        self._peak = np.zeros(N_SENSORS)
        self._count = 0
        self._block_start = 0
        keep = int(cfg.calibration_revs) + 8
        self._peaks: deque[tuple[int, np.ndarray]] = deque(maxlen=keep)  # (first sample, max)
        self.jumps: deque[Jump] = deque(maxlen=int(cfg.decision_max_revs * cfg.samples_per_rev))

    def add(self, n: int, displacement: np.ndarray) -> None:
        """
        Add one sample's probe readings (8,), m, ``[x1, y1, ..., x4, y4]``.

        A gap in the sample indices starts the differences afresh (seven samples without a
        test).
        """
        if self._last is None or n != self._last + 1:
            self._x.clear()
        self._last = n
        self._x.append(np.asarray(displacement, dtype=float))
        if len(self._x) < 8:
            return
        x7, x6, x5, x4, x3, x2, x1, x0 = self._x  # x[n-7], ..., x[n]
        s = (3.0 * (x1 - x2) + x3 - x0) / 2.0
        if self.threshold is None:
            self._keep_peak(n, np.abs(s))
            return
        ratio = np.abs(s) / self.threshold
        c = int(np.argmax(ratio))
        top = float(ratio[c])
        if top < self.config.jump_factor:
            return
        others = np.delete(ratio, c).max()
        lasting = float(x0[c] - x1[c] - x2[c] + x3[c]) - float(x4[c] - x5[c] - x6[c] + x7[c])
        if others > self.config.jump_isolation * top or abs(lasting) > (
            self.config.jump_lasting * abs(float(s[c]))
        ):
            return
        jump = (n - 1, c, top, float(s[c]))
        if self.jumps and self.jumps[-1][1] == c and self.jumps[-1][0] == n - 2:
            # a step's neighbours read half of it (module docstring): keep the larger
            if self.jumps[-1][2] >= top:
                return
            self.jumps.pop()
        self.jumps.append(jump)

    def _keep_peak(self, n: int, magnitude: np.ndarray) -> None:
        spr = self.config.samples_per_rev
        if self._count == 0:
            self._block_start = n
            self._peak = magnitude.copy()
        else:
            np.maximum(self._peak, magnitude, out=self._peak)
        self._count += 1
        if self._count == spr:
            self._peaks.append((self._block_start, self._peak.copy()))
            self._count = 0

    def calibrate(self, end: int) -> None:
        """
        Set each channel's threshold: its largest ``|s|`` in the calibration window.

        The window is that of :func:`~amb_fault_monitor.calibration.window_revolutions`,
        ending at sample ``end``; with fewer than two revolutions of displacements in it the
        test stays off.
        """
        cfg = self.config
        peaks = window_revolutions(self._peaks, end, cfg)
        if len(peaks) < 2:
            return
        self.threshold = np.maximum(np.max(peaks, axis=0), cfg.threshold_floor)

    def single_channel(self, first: int, last: int, mask: np.ndarray) -> Jump | None:
        """
        The largest jump of samples ``first..last`` if all of them are on one channel in use.

        Parameters
        ----------
        first, last : int
            Sample indices, inclusive.
        mask : numpy.ndarray
            Channels in use (8,), bool: jumps of a channel already found faulty are ignored.

        Returns
        -------
        Jump or None
            None when no jump lies in the span or when they lie on more than one channel.
        """
        found = [j for j in self.jumps if first <= j[0] <= last and mask[j[1]]]
        if not found or len({j[1] for j in found}) > 1:
            return None
        return max(found, key=lambda j: j[2])


def jump_decision(jump: Jump, factor: float) -> Decision:
    """
    The ``SENSOR_FAULT`` a jump names (its channel, plane and bearing-plane probe).

    Parameters
    ----------
    jump : Jump
    factor : float
        ``jump_factor``: the confidence grows from 0 at the test's limit.
    """
    n, channel, ratio, size = jump
    plane = channel // 2 + 1
    axis = "xy"[channel % 2]
    return Decision(
        FaultType.SENSOR_FAULT,
        plane=plane,
        channel=channel,
        severity=abs(size),
        confidence=ratio_confidence(ratio / factor),
        evidence={
            "rule": "one probe's reading jumped with its slope unchanged; no other moved",
            "jump_m": size,
            "jump_ratio": ratio,
            "jump_sample": n,
        },
        description=(
            f"probe plane {plane} {axis} (channel {channel}) jumped by {size:.3g} m at sample "
            f"{n} ({ratio:.1f} x its healthy limit) with its slope unchanged and no other probe "
            "moving: a rotor cannot, the probe reads off"
        ),
    )
