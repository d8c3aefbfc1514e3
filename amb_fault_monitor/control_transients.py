"""
Control transients: episodes the controller's own force step explains (monitor step 5).

The controller's wavelet force moves the rotor too, and a change of it from one revolution to
the next excites the same transient features as a fault (a late command, a steady synchronous
force answered by zero for one period, was called a contact). The node tells the monitor the
force applied in each sample; it is compared with the force one revolution earlier (the lag
of the features: a steady force periodic in the revolution changes nothing), and the samples
where an axis changed by more than ``control_step`` (N) form step runs (joined across gaps
under half a revolution; a one-revolution drop is a two-revolution run, the drop and the
return).

An episode is a *control transient* when a step run began before its first crossing completed
and its estimated onset lies in the run or at most ``control_window_revs`` after it (or before
it by less than the shortest crossing support, the estimate's own back-dating). Its decision
emits no event, whatever the class: it is counted (``transients``) and kept
(``last_transient``: the step, the onset and the class it would have had). The step must come
first: the controller's reaction to a disturbance begins at the earliest with the period
after the one that measured it (``delay_periods`` >= 1, 2 by default: a period later still),
so it begins after the disturbance's onset and does not excuse it. Only with
``delay_periods`` 1 and a disturbance in the last samples of a period (fewer than the
shortest crossing support, 2 with haar, up to 8 with db4 at 32 samples per revolution) can the
two not be told apart. Within such an episode, the contact bursts
(:mod:`amb_fault_monitor.bursts`) inside a step run or up to ``control_window_revs`` after it
are the response to that step (a second late command a few revolutions on re-excites the
finest level like an impulse) and are not counted; bursts outside are contacts and reported as
in any episode. Without a force step nothing changes. The price: a fault that begins while a
control transient's episode is open (its decision wait and its ring-down) is decided with it
and not reported unless its bursts rise above the ring-down envelope.

Kinks. Within a revolution, the force's own shape can ring the finest level: a command that
starts a period with a jump of its slope (the early action's transient force, unsmoothed,
stepped 320-450 N in one sample; a period-rate law's command meets the previous one with a
kink of ~20 N while it reacts) moves the rotor like an impulse at that sample, and in any
episode the contact test took it for a contact (the burst's onset at the kink's sample, in
every such run measured). A sample whose second difference of the applied force exceeds
``control_kink`` on an axis is a *kink*; a contact burst whose coefficient's support, or as
many samples before it, holds a kink is the force's response and not counted, in any episode.
A real contact in such a window is missed once; one that persists is found at its next
burst.

Limits. The bearing force (PID and wavelet force together) bends where it reaches or leaves
the actuator's limit: the clipped force's slope jumps at that sample. A loss that drives the
force to its limit for part of each revolution rings the finest level at those samples (the
430 g cm loss at 28.65 Hz on the calibrated rig: rotating-frame ratios of 10-53 at the first
entries to the limit, 1.8 revolutions before the first touch, reported as a contact; the touch
itself rings 10-30). A sample at which an axis reaches or leaves the limit
(:meth:`ControlSteps.clipped`, fed when the monitor knows the limit) explains a rise of the
*rotating*-frame finest level in the same window as a kink (:meth:`ControlSteps.limit_near`):
there the only test is the envelope of the revolution before (:mod:`~amb_fault_monitor.bursts`),
which a new bend passes. The fixed frame, where the median and step tests apply as well, is not
excused: no bend rose there in any case measured, every touch did within a few samples, and a
coil failure's first touch comes with the other coil's force reaching its limit (excusing both
frames lost that contact with db2 and db4).

Memory. Kinks and bends are kept for ``KINK_MEMORY_REVS`` revolutions, not by count: in a node
the measurements (the forces) may run revolutions ahead of the coefficients they explain, and
an early action's plan kinks in every sample, so a memory of the last 64 kinks had forgotten the
plan's first one when the burst at it was tested.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from amb_common.faults import FaultEvent
from amb_fault_monitor.onset import Crossing, estimate_onset

__all__ = ["KINK_MEMORY_REVS", "ControlSteps"]

#: Revolutions a force kink is remembered after the latest one (module notes, "Kinks").
KINK_MEMORY_REVS = 32


class ControlSteps:
    """
    Step runs of the applied control force, and the episodes they explain.

    Parameters
    ----------
    config : MonitorConfig
        Or anything with its ``samples_per_rev``, ``control_step`` and
        ``control_window_revs``.

    Attributes
    ----------
    transients : int
        Episodes decided as control transients.
    last_transient : dict or None
        The latest of them: onset and decision sample, the step run's first and last sample
        and largest change (N), and the class the episode would have had.
    """

    def __init__(self, config) -> None:
        self.config = config
        spr = config.samples_per_rev
        # plain lists: four floats per sample are cheaper in Python than in numpy calls
        self._force = [[0.0] * 4 for _ in range(spr)]
        self._force_at = [-(2**62)] * spr
        self._steps: deque[list] = deque(maxlen=32)  # [first, last, largest change N]
        self._kinks: deque[int] = deque()  # samples of a force kink, ascending (notes)
        self._kink_memory = KINK_MEMORY_REVS * spr
        self._last2: tuple[int, list, list] | None = None  # (n, force n - 1, force n)
        self._limits: tuple[int, tuple[bool, ...]] | None = None  # (n, axes at the limit)
        self._limit_kinks: deque[int] = deque()  # samples an axis reached or left it, ascending
        self.transients = 0
        self.last_transient: dict | None = None

    def record(self, sample_index: int, force: np.ndarray) -> None:
        """
        Record the force (4,), N per axis, applied during sample ``sample_index``.

        Compared with the force of ``sample_index - samples_per_rev`` (if recorded): a change
        of more than ``control_step`` on an axis extends the current step run, or starts one.
        """
        n = int(sample_index)
        spr = self.config.samples_per_rev
        slot = n % spr
        f = np.asarray(force, dtype=float).tolist()
        if self._force_at[slot] == n - spr:
            change = max(abs(a - b) for a, b in zip(f, self._force[slot], strict=True))
            if change > self.config.control_step:
                steps = self._steps
                if steps and steps[-1][0] <= n <= steps[-1][1] + spr // 2:
                    run = steps[-1]
                    run[1], run[2] = n, max(run[2], change)
                else:
                    steps.append([n, n, change])
        self._force[slot] = f
        self._force_at[slot] = n
        last = self._last2
        if last is not None and last[0] == n - 1:
            kink = max(abs(a - 2.0 * b + c) for a, b, c in zip(f, last[2], last[1], strict=True))
            if kink > self.config.control_kink:
                self._remember(self._kinks, n)
            self._last2 = (n, last[2], f)
        else:
            self._last2 = (n, f, f)  # no sample before: no slope yet

    def clipped(self, sample_index: int, at_limit: np.ndarray) -> None:
        """
        Record which axes' bearing force is at the actuator's limit during a sample.

        An axis that reaches or leaves the limit between two consecutive samples is a bend at
        the later one (module notes, "Limits"); a gap in the samples gives none.

        Parameters
        ----------
        sample_index : int
        at_limit : numpy.ndarray
            Shape ``(4,)``, bool: ``|bearing force| >= force limit`` per axis.
        """
        n = int(sample_index)
        flags = tuple(bool(a) for a in at_limit)
        last = self._limits
        if last is not None and last[0] == n - 1 and last[1] != flags:
            self._remember(self._limit_kinks, n)
        self._limits = (n, flags)

    def _remember(self, kinks: deque[int], n: int) -> None:
        while kinks and kinks[-1] > n:  # the samples went back: keep them ascending
            kinks.pop()
        while kinks and kinks[0] < n - self._kink_memory:
            kinks.popleft()
        if not kinks or kinks[-1] != n:
            kinks.append(n)

    def run_explaining(self, crossings: list[Crossing], start: int) -> list | None:
        """
        The step run ``[first, last, change]`` that explains an episode, or None.

        The run began before the episode's first crossing completed (``start``; a step at
        sample ``s`` moves the rotor from ``s + 1``), and the estimated onset lies in the run
        or at most ``control_window_revs`` after it, or before it by less than the shortest
        crossing support (the estimate is the earliest sample the change can be at).
        """
        if not crossings or not self._steps:
            return None
        window = self.config.control_window_revs * self.config.samples_per_rev
        onset = estimate_onset(crossings)
        support = min(c.last - c.first + 1 for c in crossings)
        for run in self._steps:
            if run[0] < start and run[0] < onset + support and onset <= run[1] + window:
                return run
        return None

    def kink_near(self, first: int, last: int) -> bool:
        """True if a kink lies in samples ``first..last`` or as many before (module notes)."""
        return _near(self._kinks, first, last)

    def limit_near(self, first: int, last: int) -> bool:
        """As :meth:`kink_near`, for the samples an axis reached or left the force limit."""
        return _near(self._limit_kinks, first, last)

    def in_window(self, n: int) -> bool:
        """True if sample ``n`` lies in a step run or up to ``control_window_revs`` after it."""
        window = self.config.control_window_revs * self.config.samples_per_rev
        return any(run[0] < n <= run[1] + window for run in self._steps)

    def count(self, run: list, ev: FaultEvent) -> None:
        """Count a decided episode explained by step ``run`` instead of emitting ``ev``."""
        first, last, change = run
        self.transients += 1
        self.last_transient = {
            "onset_sample_index": int(ev.onset_sample_index),
            "decision_sample_index": int(ev.decision_sample_index),
            "step_first_sample_index": int(first),
            "step_last_sample_index": int(last),
            "step_n": float(change),
            "classified_as": ev.fault_type.name,
        }


def _near(kinks: deque[int], first: int, last: int) -> bool:
    """True if ascending ``kinks`` hold a sample in ``first..last`` or as many before."""
    start = first - (last - first + 1)
    for k in reversed(kinks):  # the latest first: stop before the window
        if k < start:
            return False
        if k <= last:
            return True
    return False
