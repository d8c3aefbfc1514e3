"""
Contact bursts inside an episode's ring-down (monitor step 4; thesis figure 5.27 case 2).

A disturbance may ring on, and contacts that a mass loss leads to keep re-exciting it, while a
free ring-down decays smoothly. From one revolution after the episode's first crossing, each
finest-level coefficient (either frame) is compared with the ring-down's own envelope, the
largest finest-level ratio of the preceding revolution without its last quarter (the
coefficients overlapping this one): ``r >= tail_rise * envelope`` and ``r >= confirm_ratio``
is a new impulse, a contact.

That envelope fails where a contact comes within the first revolution: the test has not
started, and the first contact's spike then sits in the envelope and hides the next ones. So
from a quarter revolution into the episode two robust envelopes apply on the fixed-frame
finest level: the *median* since the episode began (at most one revolution back, its last
eighth excluded, which a single spike does not raise) of (a) the ratio ``r`` and (b) the
change of the coefficient from the previous one (figure 5.30 c-d, "the change in wavelet
coefficients with each sample"). A coefficient with ``r >= confirm_ratio`` and (a) or (b) at
least ``tail_rise_median`` times its median is a burst; (a) alone not if a burst was found one
revolution before (the feature's one-revolution lag echoes every spike one revolution later).
With db2 and db4 (2 and 4 vanishing moments) the finest level of a smooth ring-down stays
near the noise and a contact spikes it: (a). With haar the finest level follows the slope of
the ring-down (one vanishing moment), so a contact, a sudden change of velocity, is a step of
the coefficient: (b). Fixed frame only: an impulse is local in time in either frame, but slow
motion (base motion, below 1 x) appears near 1 x in the rotating frame, where the haar finest
level follows its slope. Together they separate a contact in the first revolution with each
wavelet. Sensor-fault episodes rise too (a noisy or offset probe spikes its finest level):
their bursts are dropped at the decision (:meth:`ContactBursts.clear`).

Each test needs ``r >= confirm_ratio``. A lighter touch of a rotor already ringing (the end of a
shaft whose bearing axis lost its coils, drifting onto its auxiliary bearing: 240 N, db4's
finest level 1.8 x its threshold) counts from ``r >= weak_burst_ratio`` when, in the fixed frame,
all three rises agree: over the ring-down's envelope, over the median and in the coefficient's
change. An impulse passes all three; the slope of a slow motion (haar) passes the median alone,
a rotating-frame ring only the envelope.

A coil failure's episode may begin with the touch itself: after the loss of one coil the
other pulls the rotor onto its auxiliary bearing within a few samples (0.1 revolution at 11
Hz), before the rise test starts, and the rotor then rests there. Its landing, a probe plane
at ``landing_fraction`` of its nearest clearance (:meth:`ContactBursts.land`), is then the
contact, where the rise test found none.

Bursts closer than ``burst_gap_revs`` are one. If the episode is decided a contact, they add
to its count; otherwise one ``AUX_BEARING_CONTACT`` event (:meth:`ContactBursts.event`) is
emitted right after the decision (or at the first contact found in the tail), onset at the
first burst, ``count`` the bursts found until then (later bursts of the same episode are not
reported again).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from amb_common.faults import FaultEvent, FaultType
from amb_fault_monitor.classifier import ratio_confidence

__all__ = ["ContactBursts"]


class ContactBursts:
    """
    The rise test of one episode and the contact bursts it found.

    Parameters
    ----------
    start : int
        Sample of the episode's first crossing.

    Attributes
    ----------
    count : int
        Bursts found (separated by more than ``burst_gap_revs``).
    onset, detection : int
        Onset (the time centre of the first burst's coefficient) and detection sample of the
        first burst; -1 before.
    peak : float
        Largest finest-level ratio of a burst.
    plane_peak : numpy.ndarray
        Largest ratio per plane (4,) of a burst.
    reported : bool
        True once the bursts were reported (as a contact decision or their own event).
    landing : numpy.ndarray or None
        The planes' shares of their clearances (4,) at a landing counted as the contact
        (:meth:`land`), else None.
    """

    def __init__(self, start: int) -> None:
        self.start = start
        self.count = 0
        self.onset = -1
        self.detection = -1
        self.peak = 0.0
        self.plane_peak = np.zeros(4)
        self.reported = False
        self.landing: np.ndarray | None = None
        self._last = -1
        self._history: deque = deque()
        self._fixed_history: deque = deque()
        self._step_history: deque = deque()
        self._rise_at: deque = deque(maxlen=64)
        self._prev_fine: np.ndarray | None = None

    def rises(self, n: int, ratio: np.ndarray, fine: np.ndarray | None, config) -> bool:
        """
        Whether the finest-level coefficient completed at ``n`` rises above the envelopes.

        Parameters
        ----------
        n : int
            Sample index.
        ratio : numpy.ndarray
            Plane ratios (4,) of the coefficient (either frame).
        fine : numpy.ndarray or None
            The fixed-frame coefficients (8,) in metres over the channels in use; None for
            the rotating frame.
        config : MonitorConfig
            Or anything with ``samples_per_rev``, ``confirm_ratio``, ``tail_rise`` and
            ``tail_rise_median``.
        """
        spr = config.samples_per_rev
        r = float(ratio.max())
        hist = self._history
        while hist and hist[0][0] < n - spr:
            hist.popleft()
        recent = max((h[1] for h in hist if h[0] <= n - spr // 4), default=0.0)
        hist.append((n, r))
        median = step_median = math.inf
        step = 0.0
        if fine is not None:
            median = _window_median(self._fixed_history, n, spr, r)
            if self._prev_fine is not None:
                d = fine - self._prev_fine
                step = float(np.hypot(d[0::2], d[1::2]).max())
                step_median = _window_median(self._step_history, n, spr, step)
            self._prev_fine = fine
        if r < config.weak_burst_ratio or n < self.start + spr // 4:
            return False
        envelope = n >= self.start + spr and r >= config.tail_rise * recent
        if r < config.confirm_ratio:  # a weak burst: every envelope agrees
            if not (
                envelope
                and r >= config.tail_rise_median * median
                and step >= config.tail_rise_median * step_median
            ):
                return False
        elif not envelope and step < config.tail_rise_median * step_median:
            if r < config.tail_rise_median * median:
                return False
            if any(abs(m + spr - n) <= 2 for m in self._rise_at):
                return False  # the one-revolution lag of the feature echoes a burst 1 rev later
        self._rise_at.append(n)
        return True

    def add(self, n: int, ratio: np.ndarray, onset: int, config) -> None:
        """
        Count a rise at sample ``n`` (plane ratios ``ratio``) as a contact burst.

        ``onset`` is the sample of its coefficient's time centre (used for the first burst).
        """
        gap = config.burst_gap_revs * config.samples_per_rev
        if self._last < 0 or n - self._last > gap:
            self.count += 1
            if self.onset < 0:
                self.onset, self.detection = onset, n
        self._last = n
        self.peak = max(self.peak, float(ratio.max()))
        self.plane_peak = np.maximum(self.plane_peak, ratio)

    def land(self, n: int, shares: np.ndarray) -> None:
        """
        Count the landing at sample ``n`` as the contact (none found by the rise test).

        ``shares``: each plane's largest radial displacement over its nearest clearance (4,)
        in the episode so far.
        """
        self.count, self.onset, self.detection, self._last = 1, n, n, n
        self.landing = np.asarray(shares, dtype=float)

    def clear(self) -> None:
        """Drop the bursts found so far (they came from a failing sensor, not the rotor)."""
        self.count, self.onset, self.detection = 0, -1, -1
        self._last, self.peak = -1, 0.0
        self.plane_peak = np.zeros(4)

    def event(self, n: int, omega: float, after: str, config) -> FaultEvent:
        """
        The ``AUX_BEARING_CONTACT`` event of the bursts so far, decided at sample ``n``.

        ``after`` names the episode's class (``"CONTROL_TRANSIENT"`` for a control
        transient). Marks the bursts reported. A landing (:meth:`land`) has its share over
        ``landing_fraction`` for the confidence, as a ratio over its limit does for every event.
        """
        self.reported = True
        if self.landing is not None:
            plane = int(np.argmax(self.landing)) + 1
            share = float(self.landing.max())
            confidence = ratio_confidence(share / config.landing_fraction)
            evidence = {
                "landing_clearance_share": share,
                "rule": f"probe plane at >= {config.landing_fraction:g} of its clearance",
            }
            description = (
                f"plane {plane} reached {share:.2f} of its auxiliary bearing's clearance after "
                f"the {after.lower()}: the rotor landed on the bearing"
            )
        else:
            plane = int(np.argmax(self.plane_peak)) + 1
            confidence = ratio_confidence(self.peak)
            evidence = {
                "peak_ratio_finest_level": self.peak,
                "rule": f"finest level >= {config.tail_rise:g} x its ring-down envelope",
            }
            control = after == "CONTROL_TRANSIENT"
            description = (
                f"{self.count} contact burst(s) at the finest level above the "
                f"envelope of the {'control' if control else after.lower()} transient"
            )
        return FaultEvent(
            FaultType.AUX_BEARING_CONTACT,
            onset_sample_index=self.onset,
            detection_sample_index=self.detection,
            decision_sample_index=n,
            samples_per_rev=config.samples_per_rev,
            omega=omega,
            plane=plane,
            confidence=confidence,
            count=self.count,
            evidence={"after": after, "bursts": self.count, **evidence},
            description=description,
        )


def _window_median(hist: deque, n: int, spr: int, value: float) -> float:
    """
    Median of ``hist`` values from one revolution to one eighth before ``n``, then append.

    ``inf`` with fewer than two values (the rise test cannot apply yet).
    """
    while hist and hist[0][0] < n - spr:
        hist.popleft()
    older = [h[1] for h in hist if h[0] <= n - spr // 8]
    hist.append((n, value))
    return float(np.median(older)) if len(older) >= 2 else math.inf
