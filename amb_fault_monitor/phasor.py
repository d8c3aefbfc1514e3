"""
The synchronous (1 x) level: whether it changed for good after an episode (thesis Table 5.1).

The synchronous phasor per channel is ``P = c_even + i c_odd`` at level ``R`` (1 x running
speed) in the fixed frame (the odd channel is delayed a quarter revolution, section 4.3, so
``|P|`` does not depend on the phase of the orbit). It is compared before and after an
episode to decide whether the synchronous level changed for good (a new steady state, Table
5.1).

With ``s_k`` the largest plane ratio of ``|P_k - P_ref|`` to its threshold for the k-th 1 x
phasor wholly after the onset (``P_ref`` the last one wholly before), the level has
*returned* when the latest ``settle_revs`` values are all below ``sync_change`` (no lasting
change: the ring-down of a contact or an impulse); it has *settled* when their spread is at
most ``settle_spread`` of their mean and their mean is at least ``sustain`` times the mean of
the ``settle_revs`` before (a new steady level, Table 5.1 "sudden mass loss"; a decaying
ring-down fails the second test). Table 5.1 asks for the new *steady state*: deciding at a
fixed delay while the transient still rings confuses the two. The threshold of each plane is
the calibrated one, or ``sync_relative_floor`` of the reference's 1 x level if larger.

Coherent: a new level is also a change of the *mean* phasor. Both "settled" and the trend at
the end of the wait need the mean of the latest ``settle_revs`` changes ``P_k - P_ref``
(complex, per channel) to be at least ``sync_change`` thresholds on some plane. A mode ringing
near running speed beats against 1 x: the magnitude of each change stays above the threshold
while its phase turns or jumps from one revolution to the next, and the mean averages out
(the AB2 rub at 67.64 Hz, with the 68.7 Hz mode ringing: ``docs/fault_monitor_notes.md``,
"The 1 x level after a rub").

The level is *moving* (:meth:`SynchronousLevel.moving`) while ``s_k >= sync_change`` on all of
the latest ``2 settle_revs`` phasors: it has not returned and still moves (a large loss whose
contacts keep it ringing), so the decision waits on up to ``decision_max_revs``. If it is
still that far from the reference when the wait ends, the change is lasting (settled).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from amb_fault_monitor.features import normalise

__all__ = ["SynchronousLevel"]


def _plane_size(p: np.ndarray) -> np.ndarray:
    """Per plane, the size of complex phasors ``(..., 8)`` (x, y pairs): ``(..., 4)``."""
    return np.hypot(np.abs(p[..., 0::2]), np.abs(p[..., 1::2]))


class SynchronousLevel:
    """
    The recent 1 x phasors of the fixed frame and the settling test on them.

    Parameters
    ----------
    config : MonitorConfig
        Or anything with its ``samples_per_rev``, ``settle_revs``, ``sync_change``,
        ``sync_relative_floor``, ``sustain`` and ``settle_spread``.
    level : int
        ``R``, the level of 1 x running speed.

    Attributes
    ----------
    threshold : numpy.ndarray or None
        Per plane threshold of the phasor change (4,), m; None until calibrated.
    support : int
        Support (samples) of the latest level-``R`` coefficient (``samples_per_rev`` before
        the first).
    """

    def __init__(self, config, level: int) -> None:
        self.config = config
        self.level = level
        self.threshold: np.ndarray | None = None
        self.support = config.samples_per_rev
        self._phasors: deque[tuple[int, int, np.ndarray]] = deque(maxlen=64)

    def add(self, even, odd, mask: np.ndarray, calibrating: bool) -> np.ndarray | None:
        """
        Add the phasor of the settled level-``R`` coefficient sets ``even`` and ``odd``.

        ``odd`` may be None (then the phasor is real). While ``calibrating``, returns the
        plane magnitudes (4,) of its change from the previous phasor over the channels in
        ``mask`` (a healthy sample for the threshold), else (or for the first) None.
        """
        p = normalise(self.level, even.values).astype(complex)
        if odd is not None:
            p = p + 1j * normalise(self.level, odd.values)
        change = None
        if calibrating and self._phasors:
            d = (p - self._phasors[-1][2]) * mask
            change = np.sqrt(np.abs(d[0::2]) ** 2 + np.abs(d[1::2]) ** 2)
        self._phasors.append((int(even.first_sample_index), int(even.last_sample_index), p))
        self.support = int(even.last_sample_index - even.first_sample_index + 1)
        return change

    def reference(self, before: int) -> np.ndarray | None:
        """The latest phasor (8,) wholly before sample ``before``, or None."""
        for _first, last, p in reversed(self._phasors):
            if last < before:
                return p
        return None

    def series(
        self, p_ref: np.ndarray | None, onset: int, mask: np.ndarray, final: bool = False
    ) -> tuple[str | None, np.ndarray, np.ndarray]:
        """
        Synchronous-level status after ``onset`` relative to ``p_ref``.

        Returns
        -------
        status : str or None
            ``"settled"``, ``"returned"`` or None (still moving; at ``final`` the trend
            decides: sustained, or at least ``sync_change`` from the reference on each of the
            latest ``2 settle_revs`` phasors (a lasting change whose ring-down contacts keep
            it moving), -> settled, else returned).
        ratio : numpy.ndarray
            (4,) mean ratio per plane over the latest ``settle_revs`` revolutions.
        change : numpy.ndarray
            (4,) latest change per plane, m.
        """
        cfg = self.config
        w = cfg.settle_revs
        zero = np.zeros(4)
        if p_ref is None or self.threshold is None:
            return ("returned" if final else None), zero, zero
        after = [p for first, _last, p in self._phasors if first >= onset]
        if len(after) < (2 * w if not final else 1):
            return ("returned" if final and len(after) == 0 else None), zero, zero
        thr = self._plane_threshold(p_ref)
        d = (np.array(after) - p_ref) * mask
        dev = _plane_size(d)
        change = dev[-1]
        ratio = dev / thr
        s = ratio.max(axis=1)
        last, prev = s[-w:], s[-2 * w : -w]
        mean_last = ratio[-w:].mean(axis=0)
        if np.all(last < cfg.sync_change):
            return "returned", mean_last, change
        # the mean phasor of the latest revolutions: a new level moves it; a mode ringing near
        # 1 x beats against it and its change averages out (module docstring, "Coherent")
        coherent = bool(np.any(_plane_size(d[-w:].mean(axis=0)) / thr >= cfg.sync_change))
        sustained = prev.size == 0 or last.mean() >= cfg.sustain * prev.mean()
        steady = prev.size and sustained and np.ptp(last) <= cfg.settle_spread * last.mean()
        if steady and coherent:
            return "settled", mean_last, change
        if final:
            away = len(s) >= 2 * w and bool(np.all(s[-2 * w :] >= cfg.sync_change))
            lasting = (sustained or away) and coherent
            return ("settled" if lasting else "returned"), mean_last, change
        return None, mean_last, change

    def moving(self, p_ref: np.ndarray | None, onset: int, mask: np.ndarray) -> bool:
        """
        True while the 1 x level still moves after ``onset``.

        That is, it stayed at least ``sync_change`` from ``p_ref`` over the latest
        ``2 settle_revs`` revolutions: it has not returned and is still settling, so the
        decision waits on up to ``decision_max_revs`` for the new steady state of Table 5.1.
        """
        if p_ref is None or self.threshold is None:
            return False
        w = 2 * self.config.settle_revs
        after = [p for first, _last, p in self._phasors if first >= onset][-w:]
        if len(after) < w:
            return False
        thr = self._plane_threshold(p_ref)
        d = (np.array(after) - p_ref) * mask
        s = (_plane_size(d) / thr).max(axis=1)
        return bool(np.all(s >= self.config.sync_change))

    def _plane_threshold(self, p_ref: np.ndarray) -> np.ndarray:
        ref_level = _plane_size(p_ref)
        return np.maximum(self.threshold, self.config.sync_relative_floor * ref_level)
