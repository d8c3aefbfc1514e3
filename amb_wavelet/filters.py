"""
Orthogonal wavelet filters taken from PyWavelets' tables (thesis section 4.4).

The analysis (decomposition) filters :math:`h_0` (low pass, scaling) and :math:`h_1`
(high pass, wavelet) and the synthesis filters :math:`g_0[n] = h_0[-n]`,
:math:`g_1[n] = h_1[-n]` of the two-channel filterbank of section 4.2.3 are the
``dec_lo``, ``dec_hi``, ``rec_lo`` and ``rec_hi`` arrays of :class:`pywt.Wavelet`,
unchanged, so that the filterbank reproduces ``pywt.dwt`` / ``pywt.wavedec``.

Only the orthogonal families are accepted (``haar``, ``dbN``, ``symN``, ``coifN``,
``dmey``): the controller of chapters 6-8 manipulates coefficients level by level, which
needs an orthonormal basis (eq. 4.16). Biorthogonal names (``biorN.M``, ``rbioN.M``) and
continuous wavelets raise :class:`~amb_wavelet.errors.WaveletNameError`.

PyWavelets' tables are orthonormal only to a finite accuracy, reported as
:attr:`FilterSet.orthonormality_error`, computed exactly from the tabulated doubles (rational
arithmetic, rounded once): below 2e-16 for ``haar``, ``dbN`` and ``coifN``, 1e-13 to 2e-11 for
``symN`` and 2.2e-3 for ``dmey`` (the discrete Meyer table is an FIR approximation). Perfect
reconstruction (eq. 4.9) holds to that accuracy, no better. A floating-point sum would bury the
first group's values in its own rounding error (a few 1e-16, different for each summation
order and BLAS kernel).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import cache, lru_cache

import numpy as np
import pywt

from amb_wavelet.errors import WaveletNameError

__all__ = ["ORTHOGONAL_FAMILIES", "FilterSet", "get_filters", "orthogonal_wavelet_names"]

#: PyWavelets short family names whose members are orthogonal.
ORTHOGONAL_FAMILIES: tuple[str, ...] = ("haar", "db", "sym", "coif", "dmey")


@lru_cache(maxsize=1)
def _orthogonal_names() -> tuple[str, ...]:
    names: list[str] = []
    for family in ORTHOGONAL_FAMILIES:
        names.extend(pywt.wavelist(family, kind="discrete"))
    return tuple(names)


def orthogonal_wavelet_names() -> list[str]:
    """
    List the orthogonal wavelet names this package accepts.

    Returns
    -------
    list of str
        PyWavelets names: ``haar``, ``db1`` ... ``db38``, ``sym2`` ... ``sym20``,
        ``coif1`` ... ``coif17`` and ``dmey`` (with PyWavelets 1.10).
    """
    return list(_orthogonal_names())


@dataclass(frozen=True)
class FilterSet:
    r"""
    Analysis and synthesis filters of one orthogonal wavelet.

    Attributes
    ----------
    wavelet : str
        PyWavelets name.
    dec_lo, dec_hi : numpy.ndarray
        Analysis filters :math:`h_0, h_1` (eq. 4.7 for Haar), shape ``(L,)``.
        ``dec_lo[k]`` multiplies ``x[n - k]`` in the causal convolution.
    rec_lo, rec_hi : numpy.ndarray
        Synthesis filters :math:`g_0, g_1` (eq. 4.10), the time reverses of the analysis
        filters.
    orthonormality_error : float
        :math:`\max_k |\sum_n h_0[n] h_0[n + 2k] - \delta[k]|`, the accuracy to which
        the PyWavelets table satisfies eq. 4.16, exact for the tabulated doubles.
    """

    wavelet: str
    dec_lo: np.ndarray
    dec_hi: np.ndarray
    rec_lo: np.ndarray
    rec_hi: np.ndarray
    orthonormality_error: float

    @property
    def length(self) -> int:
        """Filter length ``L`` (number of taps; ``2 N`` for ``dbN``)."""
        return int(self.dec_lo.size)


def _check_name(wavelet: object) -> str:
    if not isinstance(wavelet, str):
        raise WaveletNameError(
            f"wavelet must be a PyWavelets name (str), got {type(wavelet).__name__}; "
            "e.g. 'haar', 'db4', 'sym4', 'coif2', 'dmey'"
        )
    name = wavelet.strip().lower()
    if name in _orthogonal_names():
        return name
    if name in pywt.wavelist(kind="discrete"):
        raise WaveletNameError(
            f"wavelet {wavelet!r} is biorthogonal, expected an orthogonal wavelet "
            f"(families {', '.join(ORTHOGONAL_FAMILIES)}); the wavelet-domain controller "
            "needs an orthonormal basis (thesis eq. 4.16). "
            "See amb_wavelet.orthogonal_wavelet_names()"
        )
    if name in pywt.wavelist(kind="continuous"):
        raise WaveletNameError(
            f"wavelet {wavelet!r} is a continuous wavelet with no filterbank; expected an "
            "orthogonal discrete wavelet. See amb_wavelet.orthogonal_wavelet_names()"
        )
    raise WaveletNameError(
        f"unknown wavelet {wavelet!r}; expected one of haar, db1-db38, sym2-sym20, "
        "coif1-coif17, dmey. See amb_wavelet.orthogonal_wavelet_names()"
    )


@cache
def _filters(name: str) -> FilterSet:
    w = pywt.Wavelet(name)
    arrays = []
    for seq in (w.dec_lo, w.dec_hi, w.rec_lo, w.rec_hi):
        a = np.asarray(seq, dtype=float)
        a.setflags(write=False)
        arrays.append(a)
    return FilterSet(name, *arrays, orthonormality_error=_orthonormality_error(w.dec_lo))


def _orthonormality_error(taps: list[float]) -> float:
    r"""Exact :math:`\max_k |\sum_n h[n] h[n + 2k] - \delta[k]|` of doubles (eq. 4.16)."""
    h = [Fraction(t) for t in taps]
    lags = [sum(h[n] * h[n + 2 * k] for n in range(len(h) - 2 * k)) for k in range(len(h) // 2)]
    return float(max([abs(lags[0] - 1), *(abs(v) for v in lags[1:])]))


def get_filters(wavelet: str) -> FilterSet:
    """
    Return the filters of an orthogonal wavelet from PyWavelets' tables.

    Parameters
    ----------
    wavelet : str
        PyWavelets name, case-insensitive (``'haar'``, ``'db4'``, ``'sym8'``, ...).

    Returns
    -------
    FilterSet
        Read-only filter arrays (cached; do not modify).

    Raises
    ------
    WaveletNameError
        For an unknown, biorthogonal or continuous wavelet name.
    """
    return _filters(_check_name(wavelet))
