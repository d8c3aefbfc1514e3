"""
Sample weights of control and measured wavelet coefficients over one control period.

A coefficient set is described by a :class:`BasisSet`: ``weights[i, c, t]`` is the weight
of channel ``c`` at sample ``period_start + offset + t`` for coefficient ``i``.

* Control coefficients (synthesis): the force on axis ``c`` over the target period is
  ``f[n] = sum_i u_i weights[i, c, n]`` (``offset = 0``, ``L = samples_per_rev``). We use
  the block-periodised orthonormal wavelets of one period (PyWavelets
  ``mode="periodization"``, levels ``j = R - p + 1``): every force waveform stays inside
  its target period, which is what ``ControlCommand`` carries; for Haar they are exactly
  the analysis wavelets of the period.
* Measured coefficients (analysis): the causal filterbank of :mod:`amb_wavelet`
  (:func:`amb_wavelet.synthesis.basis_function`, support ending at the completing sample
  ``q 2**j - 1`` of the period); for wavelets longer than Haar the support reaches back
  into earlier periods (negative ``offset``).

Quadrature (section 4.3): the odd measured channel is the input delayed by
``quarter_delay`` samples (:mod:`amb_wavelet.frontend`, default ``samples_per_rev // 4``),
i.e. the even weights moved ``quarter_delay`` samples earlier. The odd control waveform
is the even one advanced by ``quarter_delay`` samples, circularly within the period, so
that a force equal to it is seen by the odd analysis channel as the even one sees the
even waveform. At ``p = 1`` (1 x, a quarter revolution) even and odd are exactly in
quadrature and orthogonal; at other levels the pair is only approximately so (as for
the measured pair, see :mod:`amb_wavelet.frontend`).

Ordering of the flat coefficient vector (the same as ``amb_wavelet.period`` per level):
level ``p`` (in the order given), translation ``q``, quadrature, channel.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cache

import numpy as np
import pywt

from amb_controller.errors import ControllerValueError

QUADRATURES = ("even", "odd")


@dataclass(frozen=True)
class BasisSet:
    """
    Sample weights of a set of wavelet coefficients relative to a period start.

    Attributes
    ----------
    weights : numpy.ndarray
        Shape ``(n_coefficients, n_channels, length)``.
    offset : int
        Sample (relative to the period start) of ``weights[..., 0]``; negative when the
        supports reach into earlier periods.
    labels : tuple of str
        One label per coefficient, e.g. ``"p1/q1/even/c2"``.

    """

    weights: np.ndarray
    offset: int
    labels: tuple[str, ...]

    @property
    def n_coefficients(self) -> int:
        """Number of coefficients."""
        return self.weights.shape[0]

    @property
    def n_channels(self) -> int:
        """Number of physical channels (axes or sensors)."""
        return self.weights.shape[1]


def _check_levels(levels, samples_per_rev: int) -> tuple[int, ...]:
    if samples_per_rev < 2 or samples_per_rev & (samples_per_rev - 1):
        raise ControllerValueError(
            f"samples_per_rev must be a power of two >= 2, got {samples_per_rev}"
        )
    r = int(np.log2(samples_per_rev))
    levels = tuple(int(p) for p in levels)
    if not levels or any(p < 1 or p > r for p in levels):
        raise ControllerValueError(
            f"levels must be thesis levels 1..{r} (1 = 1 x running speed), got {levels}"
        )
    return levels


def _check_quadratures(quadratures) -> tuple[str, ...]:
    quadratures = tuple(quadratures)
    if not quadratures or any(q not in QUADRATURES for q in quadratures):
        raise ControllerValueError(
            f"quadratures must be drawn from {QUADRATURES}, got {quadratures}"
        )
    return quadratures


@cache
def _periodised_wavelet(wavelet: str, samples_per_rev: int, p: int, q: int) -> np.ndarray:
    """Unit-norm periodised wavelet of thesis level p, translation q, over one period."""
    r = int(np.log2(samples_per_rev))
    with warnings.catch_warnings():
        # long wavelets at level R wrap around the period: intended (periodisation)
        warnings.simplefilter("ignore", UserWarning)
        shapes = pywt.wavedec(np.zeros(samples_per_rev), wavelet, mode="periodization", level=r)
        coeffs = [np.zeros_like(c) for c in shapes]
        coeffs[p][q - 1] = 1.0  # coeffs[0] = a_R, coeffs[1] = d_R (p = 1), coeffs[p] = d_(R-p+1)
        out = pywt.waverec(coeffs, wavelet, mode="periodization")
    out.setflags(write=False)
    return out


def control_basis(
    wavelet: str,
    samples_per_rev: int,
    levels,
    n_axes: int = 4,
    quadratures=QUADRATURES,
    quarter_delay: int | None = None,
) -> BasisSet:
    """
    Return the synthesis waveforms of the control coefficients (one period, per axis).

    Parameters
    ----------
    wavelet : str
        Orthogonal PyWavelets name.
    samples_per_rev : int
        Samples per period (power of two).
    levels : sequence of int
        Thesis levels ``p`` (1 = 1 x).
    n_axes : int
        Bearing control axes.
    quadratures : sequence of {"even", "odd"}
        Quadrature channels.
    quarter_delay : int, optional
        Advance of the odd waveform in samples (default ``samples_per_rev // 4``).

    Returns
    -------
    BasisSet
        ``offset = 0``, length ``samples_per_rev``; force in N per coefficient in
        N * sqrt(samples).

    """
    levels = _check_levels(levels, samples_per_rev)
    quadratures = _check_quadratures(quadratures)
    d = samples_per_rev // 4 if quarter_delay is None else int(quarter_delay)
    rows, labels = [], []
    for p in levels:
        for q in range(1, 2 ** (p - 1) + 1):
            even = _periodised_wavelet(wavelet, samples_per_rev, p, q)
            for quad in quadratures:
                vector = even if quad == "even" else np.roll(even, -d)
                for axis in range(n_axes):
                    w = np.zeros((n_axes, samples_per_rev))
                    w[axis] = vector
                    rows.append(w)
                    labels.append(f"p{p}/q{q}/{quad}/c{axis}")
    return BasisSet(np.array(rows), 0, tuple(labels))


def measurement_basis(
    wavelet: str,
    samples_per_rev: int,
    levels,
    n_channels: int = 8,
    quadratures=QUADRATURES,
    quarter_delay: int | None = None,
) -> BasisSet:
    """
    Return the analysis weights of the measured period coefficients ``x_{p,q}(kT)``.

    The weights are those of the causal filterbank of :mod:`amb_wavelet` (equal to
    ``pywt.upcoef``), ending at the completing sample ``q 2**j - 1`` of the period.

    Parameters
    ----------
    wavelet : str
        Orthogonal PyWavelets name.
    samples_per_rev : int
        Samples per period (power of two).
    levels : sequence of int
        Thesis levels ``p``.
    n_channels : int
        Sensor channels.
    quadratures : sequence of {"even", "odd"}
        Quadrature channels.
    quarter_delay : int, optional
        Delay of the odd channel in samples (default ``samples_per_rev // 4``).

    Returns
    -------
    BasisSet

    """
    levels = _check_levels(levels, samples_per_rev)
    quadratures = _check_quadratures(quadratures)
    d = samples_per_rev // 4 if quarter_delay is None else int(quarter_delay)
    r = int(np.log2(samples_per_rev))
    pieces = []
    for p in levels:
        j = r - p + 1
        psi = pywt.upcoef("d", [1.0], wavelet, level=j)[
            : (2**j - 1) * (pywt.Wavelet(wavelet).dec_len - 1) + 1
        ]
        for q in range(1, 2 ** (p - 1) + 1):
            start = q * 2**j - psi.size
            for quad in quadratures:
                shift = 0 if quad == "even" else d
                for channel in range(n_channels):
                    pieces.append((start - shift, psi, channel, f"p{p}/q{q}/{quad}/c{channel}"))
    offset = min(s for s, *_ in pieces)
    length = samples_per_rev - offset
    weights = np.zeros((len(pieces), n_channels, length))
    for i, (start, psi, channel, _) in enumerate(pieces):
        weights[i, channel, start - offset : start - offset + psi.size] = psi
    return BasisSet(weights, offset, tuple(label for *_, label in pieces))
