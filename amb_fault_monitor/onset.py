"""
Threshold crossings and the onset back-dated from them (thesis section 5.2).

A :class:`Crossing` is one coefficient whose feature exceeded its threshold; its support (the
samples the coefficient depends on) bounds where the change that made it cross can lie.
:func:`estimate_onset` takes the onset of an episode from its first crossings, at the time
centre of the strongest one's atom (:class:`AtomCentres`, from
:func:`amb_wavelet.synthesis.atom_time_centre`).
"""

from __future__ import annotations

import math

from amb_fault_monitor.errors import FaultMonitorError
from amb_wavelet.analysis import DETAIL
from amb_wavelet.filters import get_filters
from amb_wavelet.levels import support_length
from amb_wavelet.synthesis import atom_time_centre

__all__ = ["AtomCentres", "Crossing", "estimate_onset", "onset_sample"]


class Crossing(tuple):
    """
    ``(level, frame, plane, first, last, ratio, centre)`` of a threshold crossing.

    ``first`` and ``last`` are the sample indices of the coefficient's support, ``centre`` the
    time centre of its atom (sample index, :func:`amb_wavelet.synthesis.atom_time_centre`;
    ``first`` when the wavelet is not known).
    """

    __slots__ = ()

    def __new__(
        cls,
        level: int,
        frame: str,
        plane: int,
        first: int,
        last: int,
        ratio: float,
        centre: float | None = None,
    ):
        """Make a crossing (``centre`` None: no atom centre known)."""
        return super().__new__(
            cls, (level, frame, plane, first, last, ratio, first if centre is None else centre)
        )

    level = property(lambda s: s[0])
    frame = property(lambda s: s[1])
    plane = property(lambda s: s[2])
    first = property(lambda s: s[3])
    last = property(lambda s: s[4])
    ratio = property(lambda s: s[5])
    centre = property(lambda s: s[6])


def estimate_onset(crossings: list[Crossing]) -> int:
    """
    Onset sample from the crossings of an episode (back-dated within the wavelet support).

    The coefficients that crossed first (the earliest completion sample) bound the onset:
    the change that made them cross lies in their supports. Among them the strongest (largest
    ratio to its threshold) is the one whose support surely holds the change, and within that
    support the estimate is the time centre of its atom (the earlier sample when it falls
    between two), where the coefficient is most sensitive to a change of its input
    (:func:`amb_wavelet.synthesis.atom_time_centre`). Thesis section 5.2 back-dates by the
    support; the centre is its best single sample.

    Parameters
    ----------
    crossings : list of Crossing
        Of one episode, any order.

    Returns
    -------
    int
        Estimated onset sample index.
    """
    if not crossings:
        raise FaultMonitorError("estimate_onset needs at least one crossing")
    first = min(c.last for c in crossings)
    strongest = max((c for c in crossings if c.last == first), key=lambda c: c.ratio)
    return onset_sample(strongest.centre)


def onset_sample(centre: float) -> int:
    """The sample of an atom's time centre: the nearest, the earlier one when midway."""
    return math.ceil(centre - 0.5)


class AtomCentres:
    """
    Time centres of the atoms of a stream's coefficients (cached per wavelet, level, kind, size).

    Attributes
    ----------
    wavelet : str
        The stream's mother wavelet (PyWavelets name; ``""`` when not known), set by the
        caller from each record.
    """

    def __init__(self) -> None:
        self.wavelet = ""
        self._offsets: dict[tuple[str, int, str, int], float] = {}

    def centre(self, s) -> float:
        """
        Time centre (sample index) of the atom of coefficient set ``s`` (``estimate_onset``).

        The first sample of the support when the stream's wavelet is unknown or its atom does
        not span the support (a filterbank other than ``amb_wavelet``'s). ``s.level`` of an
        approximation counts one level deeper (as the monitor files it).
        """
        level = s.level if s.kind == DETAIL else s.level - 1
        size = s.last_sample_index - s.first_sample_index + 1
        key = (self.wavelet, level, s.kind, size)
        offset = self._offsets.get(key)
        if offset is None:
            offset = 0.0
            try:
                if support_length(level, get_filters(self.wavelet).length) == size:
                    offset = atom_time_centre(self.wavelet, level, s.kind)
            except ValueError:  # not a PyWavelets name (WaveletNameError)
                pass
            self._offsets[key] = offset
        return s.first_sample_index + offset
