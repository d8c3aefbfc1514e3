"""
The monitor's input: every wavelet coefficient completed by one sample (one record per sample).

A :class:`SampleCoefficients` carries what one ``amb_msgs/WaveletCoefficients`` message
carries (thesis figure 4.3: the coefficients whose support the sample completed), with one
:class:`CoefficientSet` per (level, kind, frame, quadrature) and 8 values per set in the
sensor order ``[x1, y1, ..., x4, y4]`` (``u, v`` in the rotating frame). The node builds it
from messages; the evaluation drives it from the filterbank core directly through
:class:`FilterbankAdapter`, so both paths feed the monitor the same numbers.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from amb_common.names import N_SENSORS
from amb_wavelet.analysis import AnalysisFilterbank
from amb_wavelet.frontend import FRAMES, QUADRATURES, ChannelFrontEnd
from amb_wavelet.levels import revolution_level

__all__ = ["CoefficientSet", "FilterbankAdapter", "SampleCoefficients"]


class CoefficientSet(NamedTuple):
    """
    The coefficients of one (level, kind, frame, quadrature) completed by one sample.

    Attributes
    ----------
    level : int
        Dyadic level ``j`` (1 = finest; pseudo-frequency ``samples_per_rev / 2**j`` x speed).
    kind : str
        ``"detail"`` or ``"approximation"``.
    frame : str
        ``"fixed"`` (x, y) or ``"rotating"`` (u, v; thesis eq. 2.26, 5.2).
    quadrature : str
        ``"even"`` (as measured) or ``"odd"`` (delayed a quarter revolution, section 4.3).
    translation_index : int
        Index ``m`` of the coefficient at its level.
    first_sample_index, last_sample_index : int
        Support of the coefficient (samples).
    values : numpy.ndarray
        Shape ``(8,)``, m * sqrt(samples) (orthonormal filters, eq. 4.6).
    settled : bool
        False while start-up zeros are inside the support.
    """

    level: int
    kind: str
    frame: str
    quadrature: str
    translation_index: int
    first_sample_index: int
    last_sample_index: int
    values: np.ndarray
    settled: bool


class SampleCoefficients(NamedTuple):
    """
    All coefficients completed by one sample.

    Attributes
    ----------
    sample_index : int
        The completing sample.
    omega : float
        Running speed at that sample, rad/s.
    sets : tuple of CoefficientSet
        Possibly empty (even sample indices complete no coefficient).
    wavelet : str
        PyWavelets name of the mother wavelet (the message's ``wavelet``); ``""`` if unknown
        (the monitor then back-dates a crossing to the first sample of its support instead of
        its atom's time centre).
    """

    sample_index: int
    omega: float
    sets: tuple[CoefficientSet, ...]
    wavelet: str = ""


class FilterbankAdapter:
    """
    Measurement samples in, :class:`SampleCoefficients` out, through the ``amb_wavelet`` core.

    The same front end (frames, quadrature) and causal filterbank as the
    ``wavelet_filterbank`` node, without ROS.

    Parameters
    ----------
    samples_per_rev : int
        Samples per revolution (power of two >= 4).
    wavelet : str
        PyWavelets name (orthogonal).
    levels : int, optional
        Filterbank levels ``J``; default ``log2(samples_per_rev) + 1`` (down to 0.5 x, as in
        section 5.3).
    frames, quadrature : sequence of str
        As :class:`amb_wavelet.frontend.ChannelFrontEnd`.
    """

    def __init__(
        self,
        samples_per_rev: int,
        wavelet: str = "haar",
        levels: int | None = None,
        frames: Sequence[str] = FRAMES,
        quadrature: Sequence[str] = QUADRATURES,
    ) -> None:
        self.samples_per_rev = int(samples_per_rev)
        self.levels = int(levels) if levels else revolution_level(samples_per_rev) + 1
        self.front = ChannelFrontEnd(samples_per_rev, frames, quadrature)
        self.bank = AnalysisFilterbank(wavelet, self.levels, self.front.n_channels)
        self.frames = tuple(f for f in FRAMES if f in frames)
        self.quadrature = tuple(q for q in QUADRATURES if q in quadrature)
        self._slots = [(f, q) for f in self.frames for q in self.quadrature]
        self._started = False

    @property
    def wavelet(self) -> str:
        """PyWavelets name."""
        return self.bank.wavelet

    def reset(self, start_sample_index: int = 0) -> None:
        """Clear the filter state; the next sample must carry ``start_sample_index``."""
        self.front.reset()
        self.bank.reset(start_sample_index)
        self._started = True

    def step(
        self, sample_index: int, displacement: ArrayLike, angle: float, omega: float
    ) -> SampleCoefficients:
        """
        Analyse one sample.

        Parameters
        ----------
        sample_index : int
            Index of the sample (consecutive after :meth:`reset`).
        displacement : array_like
            Shape ``(8,)``, m.
        angle : float
            Rotor angle, rad.
        omega : float
            Running speed, rad/s.

        Returns
        -------
        SampleCoefficients
        """
        if not self._started:
            self.reset(sample_index)
        coeffs = self.bank.step(self.front.step(displacement, angle), sample_index)
        sets = []
        n = N_SENSORS
        for c in coeffs:
            for i, (frame, quad) in enumerate(self._slots):
                sets.append(
                    CoefficientSet(
                        c.level,
                        c.kind,
                        frame,
                        quad,
                        c.translation_index,
                        c.first_sample_index,
                        c.last_sample_index,
                        c.values[i * n : (i + 1) * n],
                        c.settled,
                    )
                )
        return SampleCoefficients(int(sample_index), float(omega), tuple(sets), self.wavelet)
