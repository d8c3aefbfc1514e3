"""
The evidence of one episode, from its first crossing to its decision and tail.

An :class:`Episode` collects what the classifier (:mod:`amb_fault_monitor.classifier`)
needs: the largest ratio per (level, frame) and plane, the crossings (for the onset,
:func:`amb_fault_monitor.onset.estimate_onset`), the fixed-frame change energy per channel,
over all levels and at the finest level alone (rule 1, sensor fault), the plane coherence
and size of the fixed-frame changes below 1 x and the largest change above 1 x (rule 2, base
motion), and the bursts of crossings above 1 x (rule 4, the contact count). It is confirmed
(``alarm``) on a strong crossing or on crossings of several features, and carries the contact
bursts of its ring-down (:class:`amb_fault_monitor.bursts.ContactBursts`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from amb_common.faults import WITHDRAWN, FaultEvent
from amb_common.names import N_SENSORS
from amb_fault_monitor.bursts import ContactBursts
from amb_fault_monitor.classifier import EpisodeEvidence
from amb_fault_monitor.errors import FaultMonitorError
from amb_fault_monitor.onset import Crossing, onset_sample

__all__ = ["Episode"]


@dataclass
class Episode:
    """
    One disturbance being tracked: its evidence, alarm, decision and contact bursts.

    Attributes
    ----------
    start : int
        Sample of the first crossing.
    crossings : list of Crossing
        Every crossing before the decision.
    alarm : int or None
        Sample of the confirmed detection.
    last_crossing : int
        Sample of the latest crossing (or contact burst in the tail).
    p_ref : numpy.ndarray or None
        The 1 x phasor (8,) before the episode (:mod:`amb_fault_monitor.phasor`).
    decided : FaultEvent or None
        The decision, once made (the episode is then in its tail).
    strong_only : bool
        Only a strong crossing (``confirm_ratio``) confirms it (it began in the re-arm time
        after another episode).
    control : list, bool or None
        The control step run explaining it (:mod:`amb_fault_monitor.control_transients`),
        False when none; None until looked up.
    contacts : ContactBursts
        The contact bursts found in it.
    explained : str
        The fault it is the consequence of (``COIL_FAILURE``: monitor notes, step 6), or "".
    landing : tuple or None
        ``(sample, shares)``: the first sample of the episode at which a probe plane reached
        ``landing_fraction`` of its clearance, and each plane's largest share of its clearance
        (4,) since (:meth:`FaultMonitor.displacements`); None before.
    provisional : FaultEvent or None
        Its provisional class, once published (monitor notes, step 3).
    provisional_due : bool
        Its provisional class is still to be given (False once given, or skipped for an
        episode a control step or a coil failure explains).
    first_strongest : Crossing or None
        The crossing :func:`amb_fault_monitor.onset.estimate_onset` takes from ``crossings``
        (the strongest of the earliest completed; the first added of equals), kept up to date
        as crossings are added.
    """

    start: int
    crossings: list[Crossing] = field(default_factory=list)
    keys: set = field(default_factory=set)
    alarm: int | None = None
    last_crossing: int = 0
    max_ratio: dict = field(default_factory=dict)  # (level, frame) -> (4,) plane ratios
    channel_energy: np.ndarray = field(default_factory=lambda: np.zeros(N_SENSORS))
    fine_energy: np.ndarray = field(default_factory=lambda: np.zeros(N_SENSORS))
    bursts: list = field(default_factory=list)  # [start, end, max ratio fixed, max rotating]
    p_ref: np.ndarray | None = None
    decided: FaultEvent | None = None
    strong_only: bool = False
    control: list | bool | None = None
    low_coherent: float = 0.0
    low_energy: float = 0.0
    coherent: float = 0.0  # the same over every fixed-frame crossing (any level)
    coherence_energy: float = 0.0
    low_peak: float = 0.0
    high_peak: float = 0.0
    contacts: ContactBursts = field(init=False)
    first_strongest: Crossing | None = None  # estimate_onset's crossing, kept as they come
    explained: str = ""
    landing: tuple[int, np.ndarray] | None = None
    provisional: FaultEvent | None = None
    provisional_due: bool = True

    def __post_init__(self) -> None:
        self.contacts = ContactBursts(self.start)

    def onset(self) -> int:
        """The onset sample :func:`amb_fault_monitor.onset.estimate_onset` gives its crossings."""
        if self.first_strongest is None:
            raise FaultMonitorError("an episode without crossings has no onset")
        return onset_sample(self.first_strongest.centre)

    def track(self, level: int, frame: str, ratio: np.ndarray) -> None:
        """Keep the largest plane ratios (4,) of (``level``, ``frame``)."""
        key = (level, frame)
        prev = self.max_ratio.get(key)
        self.max_ratio[key] = ratio.copy() if prev is None else np.maximum(prev, ratio)

    def add_crossings(
        self,
        n: int,
        level: int,
        frame: str,
        s,
        ratio: np.ndarray,
        delta: np.ndarray,
        thr: np.ndarray,
        centre: float,
        revolution_level: int,
        mask: np.ndarray,
        config,
        finest: int,
    ) -> None:
        """
        Add the crossings of the coefficient set ``s`` completed at ``n`` (some ``ratio > 1``).

        ``delta`` is its change (8,) in metres, ``thr`` the plane thresholds (4,), ``centre``
        the time centre of its atom, ``mask`` the channels in use, ``finest`` the finest level
        monitored (its fixed-frame changes also go to ``fine_energy``); ``config`` gives
        ``samples_per_rev``, ``burst_gap_revs``, ``confirm_ratio`` and ``confirm_features``.
        Confirms the episode (``alarm = n``) on a crossing of at least ``confirm_ratio`` or
        crossings in ``confirm_features`` different (level, frame) features (unless
        ``strong_only``).
        """
        crossed = ratio > 1.0
        self.last_crossing = n
        for p in np.flatnonzero(crossed):
            c = Crossing(level, frame, int(p) + 1, s.first_sample_index, s.last_sample_index,
                         float(ratio[p]), centre)  # fmt: skip
            self.crossings.append(c)
            # estimate_onset's choice, updated per crossing instead of a scan of all of them
            # per sample (hundreds after a control step: most of the monitor's time then)
            best = self.first_strongest
            if best is None or c.last < best.last or (c.last == best.last and c.ratio > best.ratio):
                self.first_strongest = c
        key = (level, frame)
        self.keys.add(key)
        if frame == "fixed":
            w = np.repeat(thr, 2)
            energy = (delta / w) ** 2
            self.channel_energy += energy
            if level == finest:
                self.fine_energy += energy
            coherent, total = _plane_coherence(delta, mask)
            self.coherent += coherent
            self.coherence_energy += total
            if level > revolution_level:
                self.add_low_change(delta, mask)
            elif level < revolution_level:
                self.high_peak = max(self.high_peak, float(np.abs(delta).max()))
        if level < revolution_level:
            rmax = float(ratio.max())
            gap = config.burst_gap_revs * config.samples_per_rev
            if self.bursts and n - self.bursts[-1][1] <= gap:
                b = self.bursts[-1]
                b[1] = n
            else:
                b = [n, n, 0.0, 0.0]
                self.bursts.append(b)
            b[2 if frame == "fixed" else 3] = max(b[2 if frame == "fixed" else 3], rmax)
        if self.alarm is None and (
            float(ratio.max()) >= config.confirm_ratio
            or (len(self.keys) >= config.confirm_features and not self.strong_only)
        ):
            self.alarm = n

    def withdrawal(self, explained_by: str) -> list[FaultEvent]:
        """
        A copy of the published provisional event that says it is void, or nothing.

        For an episode that turns out to be the consequence of another fault, named by
        ``explained_by`` (monitor notes, step 3).
        """
        if self.provisional is None:
            return []
        evidence = {**self.provisional.evidence, "status": WITHDRAWN, "explained_by": explained_by}
        return [replace(self.provisional, evidence=evidence)]

    def add_low_change(self, delta: np.ndarray, mask: np.ndarray) -> None:
        """
        Accumulate a fixed-frame change (8,) below 1 x: plane coherence (classifier rule 2).

        Per axis, over the channels in ``mask``, ``(sum_p a_p)**2`` and ``P sum_p a_p**2``;
        their ratio over the episode is ``low_coherence``, 1 when the planes move alike.
        """
        coherent, total = _plane_coherence(delta, mask)
        self.low_coherent += coherent
        self.low_energy += total
        self.low_peak = max(self.low_peak, float(np.abs(delta).max()))

    def evidence(
        self,
        revolution_level: int,
        sync_ratio: np.ndarray,
        sync_change: np.ndarray,
        mask: np.ndarray,
    ) -> EpisodeEvidence:
        """What the classifier needs, with the 1 x level's ratio and change (4,) and ``mask``."""
        return EpisodeEvidence(
            revolution_level=revolution_level,
            max_ratio={k: v.copy() for k, v in self.max_ratio.items()},
            channel_energy=self.channel_energy.copy(),
            fine_energy=self.fine_energy.copy(),
            sync_ratio=sync_ratio,
            sync_change=sync_change,
            bursts=[tuple(b) for b in self.bursts],
            mask=mask.copy(),
            low_coherence=self.low_coherent / self.low_energy if self.low_energy > 0 else 0.0,
            coherence=(self.coherent / self.coherence_energy if self.coherence_energy > 0 else 0.0),
            low_peak=self.low_peak,
            high_peak=self.high_peak,
        )


def _plane_coherence(delta: np.ndarray, mask: np.ndarray) -> tuple[float, float]:
    """
    ``(sum_p a_p)**2`` and ``P sum_p a_p**2`` of a change (8,), summed over both axes.

    ``a_p`` the change of plane ``p`` along the axis, over the channels in ``mask`` (axes with
    fewer than two left out); the first over the second is 1 when the planes move alike.
    """
    coherent = total = 0.0
    for axis in (0, 1):
        d = delta[axis::2][mask[axis::2]]
        if d.size < 2:
            continue
        coherent += float(d.sum()) ** 2
        total += d.size * float(d @ d)
    return coherent, total
