"""
Causal synthesis (reconstruction) filterbank, streaming and block (eq. 4.9-4.11, 4.15).

The orthonormal expansion of eq. 4.15 writes the signal as a sum of basis functions,
one per coefficient: ``x[n] = sum_j sum_m d_j[m] psi_{j,m}[n] + sum_m a_J[m] phi_{J,m}[n]``
(lower half of figure 4.3: up-sample by two and filter with :math:`g_0, g_1` at each
level). ``psi_{j,m}`` is the synthesis impulse response of one level-``j`` detail
coefficient (:func:`basis_function`; equal to ``pywt.upcoef``), occupying exactly the
support of the coefficient (module :mod:`amb_wavelet.analysis`).

Delay
-----
A causal synthesis can only add a basis function once its coefficient is complete. With
``J`` levels and filters of length ``L`` the output is

    ``y[n] = x[n - D]``,   ``D = (2**J - 1)(L - 1)``   (:func:`~amb_wavelet.levels.synthesis_delay`)

exactly (to the orthonormality of the filter table, :class:`~amb_wavelet.filters.FilterSet`):
the basis function of a coefficient completed at sample ``c`` is placed at output samples
``c + D - support + 1 .. c + D``, which all lie at or after ``c``. For Haar, ``D =
2**J - 1``: the thesis's polyphase causality delay ``N - 1`` (section 4.2.4) with
``N = 2**J``. For any set of coefficients (e.g. the control coefficients
:math:`f_{a,b}(kT)` of eq. 6.4, chosen by the controller), the output is
``y[n] = sum c psi[n - D]``, the force waveform delayed by ``D`` samples; a controller
that wants the waveform to start at a given sample adds its coefficients ``D`` samples
earlier (i.e. uses the translation index whose support ends ``D`` samples later), or
uses :func:`basis_function` directly.

Relation to PyWavelets: for coefficient arrays in the layout of
``pywt.wavedec(..., mode="zero")`` (leading rows as produced by the causal analysis,
the remaining rows zero), ``y[n + D] == pywt.waverec(coeffs, wavelet, mode="zero")[n]``.
"""

from __future__ import annotations

from collections.abc import Iterable
from functools import cache

import numpy as np
from numpy.typing import ArrayLike
from scipy.signal import upfirdn

from amb_wavelet.analysis import APPROXIMATION, DETAIL, Coefficient, Decomposition
from amb_wavelet.filters import get_filters
from amb_wavelet.levels import check_level, support_length, synthesis_delay

__all__ = ["SynthesisFilterbank", "atom_time_centre", "basis_function", "synthesize_block"]


@cache
def _basis(wavelet: str, level: int, kind: str) -> np.ndarray:
    f = get_filters(wavelet)
    out = np.array([1.0])
    # level j basis: g1 (or g0 for the approximation) up-sampled by 2**(j-1), convolved
    # with g0 up-sampled by 2**(j-2), ..., g0 (eq. 4.14-4.15 unrolled)
    for i in range(level - 1, -1, -1):
        g = f.rec_lo if (i < level - 1 or kind == APPROXIMATION) else f.rec_hi
        up = np.zeros((g.size - 1) * 2**i + 1)
        up[:: 2**i] = g
        out = np.convolve(out, up)
    out.setflags(write=False)
    return out


def basis_function(wavelet: str, level: int, kind: str = DETAIL) -> np.ndarray:
    r"""
    Return the discrete orthonormal wavelet (or scaling) function of one coefficient.

    Parameters
    ----------
    wavelet : str
        Orthogonal PyWavelets name.
    level : int
        Level ``j >= 1``.
    kind : {"detail", "approximation"}
        Wavelet function :math:`\psi` or scaling function :math:`\phi`.

    Returns
    -------
    numpy.ndarray
        Shape ``((2**j - 1)(L - 1) + 1,)``, unit 2-norm (read-only). Element ``t`` is the
        weight of sample ``first_sample_index + t`` of the coefficient's support; equals
        ``pywt.upcoef("d" or "a", [1.0], wavelet, level=j)``. Sampled at ``fs`` it is the
        wavelet of figures 4.7, 4.9 and 4.10 dilated to ``2**j`` samples per unit time,
        scaled by ``2**(-j/2)``.
    """
    if kind not in (DETAIL, APPROXIMATION):
        raise ValueError(f"kind must be {DETAIL!r} or {APPROXIMATION!r}, got {kind!r}")
    return _basis(get_filters(wavelet).wavelet, check_level(level), kind)


@cache
def atom_time_centre(wavelet: str, level: int, kind: str = DETAIL) -> float:
    r"""
    Return the time centre of one coefficient's atom, in samples after its first sample.

    The centre of the time-energy distribution of the unit-norm atom ``b`` of
    :func:`basis_function`, :math:`u = \sum_t t\, b_t^2` (Mallat's time centre; eq. 4.34
    measures the spread about the same kind of centre, for the scaling filter). It is where the
    coefficient is most sensitive to a change of its input: the fault monitor back-dates a
    threshold crossing to it (:func:`amb_fault_monitor.onset.estimate_onset`).
    Daubechies atoms (extremal phase) have their energy late in the support, on the most
    recent samples: db4 at level 1 ``u = 5.54`` of 0..7; Haar's is the middle.

    Parameters
    ----------
    wavelet : str
        Orthogonal PyWavelets name.
    level : int
        Level ``j >= 1``.
    kind : {"detail", "approximation"}
        Wavelet or scaling function.

    Returns
    -------
    float
        ``u`` in samples, ``0 <= u <= support_length - 1``.
    """
    b = basis_function(wavelet, level, kind)
    e = b * b
    return float(np.arange(b.size) @ e / e.sum())


def _offsets(level: int, L: int, D: int) -> int:
    """Output index of the basis start for translation index 0 at ``level``."""
    return 2**level - 1 + D - support_length(level, L) + 1


def synthesize_block(decomposition: Decomposition, n_samples: int | None = None) -> np.ndarray:
    """
    Reconstruct a block from its coefficients, delayed by the causal synthesis delay.

    Parameters
    ----------
    decomposition : Decomposition
        Coefficients as returned by :func:`~amb_wavelet.analysis.analyze_block` (or any
        arrays of that layout, e.g. control coefficients; ``translation_start`` honoured).
    n_samples : int, optional
        Number of output samples (output indices ``0 .. n_samples - 1``). Default:
        ``2 * (translation_start[0] + len(details[0]))``.

    Returns
    -------
    numpy.ndarray
        ``y`` of shape ``(n_samples,) + channel shape`` with
        ``y[n] = sum_{j,m} c_j[m] psi_{j,m}[n - D]``; for coefficients of a signal ``x``
        started at index 0, ``y[n] = x[n - D]`` (``0`` for ``n < D``).
    """
    dec = decomposition
    J = dec.level
    f = get_filters(dec.wavelet)
    L = f.length
    D = synthesis_delay(J, L)
    if n_samples is None:
        n_samples = 2 * (dec.translation_start[0] + len(dec.details[0]))
    n_samples = int(n_samples)
    tail = dec.approximation.shape[1:]
    y = np.zeros((n_samples, *tail))
    items = [(j + 1, DETAIL, d, dec.translation_start[j]) for j, d in enumerate(dec.details)]
    items.append((J, APPROXIMATION, dec.approximation, dec.translation_start[J - 1]))
    for level, kind, coeffs, m0 in items:
        c = np.asarray(coeffs, dtype=float)
        if c.shape[0] == 0:
            continue
        g = _basis(dec.wavelet, level, kind)
        contrib = upfirdn(g, c, up=2**level, axis=0)  # sum_m c[m] g[k - 2**level m]
        start = 2**level * m0 + _offsets(level, L, D)
        lo, hi = max(start, 0), min(start + contrib.shape[0], n_samples)
        if hi > lo:
            y[lo:hi] += contrib[lo - start : hi - start]
    return y


class SynthesisFilterbank:
    """
    Streaming causal synthesis: coefficients in, one output sample per :meth:`step`.

    Parameters
    ----------
    wavelet : str
        Orthogonal PyWavelets name.
    level : int
        Number of levels ``J`` (the deepest level whose approximation is accepted).
    n_channels : int
        Channels ``C``.
    start_sample_index : int
        Index of the first output sample.

    Notes
    -----
    Output sample ``n`` is ``y[n] = sum c psi[n - D]`` over all coefficients added so
    far (:attr:`delay` ``D``). Feeding each sample's coefficients from an
    :class:`~amb_wavelet.analysis.AnalysisFilterbank` of the same wavelet and level into
    :meth:`step` gives ``y[n] = x[n - D]``.
    """

    def __init__(
        self, wavelet: str, level: int, n_channels: int, start_sample_index: int = 0
    ) -> None:
        self._wavelet = get_filters(wavelet).wavelet
        self._level = check_level(level)
        if isinstance(n_channels, bool) or not isinstance(n_channels, int) or n_channels < 1:
            raise ValueError(f"n_channels must be an int >= 1, got {n_channels!r}")
        self._C = n_channels
        L = get_filters(wavelet).length
        self._D = synthesis_delay(self._level, L)
        self._basis = {
            (j, DETAIL): _basis(self._wavelet, j, DETAIL) for j in range(1, self._level + 1)
        }
        self._basis[(self._level, APPROXIMATION)] = _basis(
            self._wavelet, self._level, APPROXIMATION
        )
        self._off = {j: _offsets(j, L, self._D) for j in range(1, self._level + 1)}
        self._acc = np.zeros((2 * (self._D + 2**self._level + 1), n_channels))
        self.reset(start_sample_index)

    @property
    def delay(self) -> int:
        """Synthesis delay ``D`` (samples), see :func:`~amb_wavelet.levels.synthesis_delay`."""
        return self._D

    @property
    def next_sample_index(self) -> int:
        """Index of the next output sample :meth:`step` returns."""
        return self._next

    def reset(self, start_sample_index: int = 0) -> None:
        """
        Drop all pending contributions.

        Parameters
        ----------
        start_sample_index : int
            Index of the next output sample.
        """
        if isinstance(start_sample_index, bool) or int(start_sample_index) != start_sample_index:
            raise ValueError(f"start_sample_index must be an int, got {start_sample_index!r}")
        self._acc[...] = 0.0
        self._head = 0
        self._next = int(start_sample_index)

    def add(self, level: int, kind: str, translation_index: int, values: ArrayLike) -> None:
        """
        Add one coefficient's basis function to the pending output.

        Parameters
        ----------
        level : int
            Level ``1 .. J`` (``J`` only for ``kind="approximation"``).
        kind : {"detail", "approximation"}
            Coefficient kind.
        translation_index : int
            ``m``; the basis function occupies output samples
            ``2**level (m + 1) + D - support .. 2**level (m + 1) - 1 + D``.
        values : array_like
            Shape ``(C,)``.

        Raises
        ------
        ValueError
            If the basis function would start at an output sample already returned (the
            coefficient came too late), or for a bad level, kind or shape.
        """
        g = self._basis.get((level, kind))
        if g is None:
            raise ValueError(
                f"no basis for level={level!r}, kind={kind!r}: expected a detail of level "
                f"1..{self._level} or the approximation of level {self._level}"
            )
        v = np.asarray(values, dtype=float)
        if v.shape != (self._C,):
            raise ValueError(f"values must have shape ({self._C},), got {v.shape}")
        start = 2**level * int(translation_index) + self._off[level]
        rel = start - self._next
        if rel < 0:
            raise ValueError(
                f"coefficient (level {level}, {kind}, m={translation_index}) contributes "
                f"from output sample {start}, but samples up to {self._next - 1} were "
                "already returned; add coefficients no later than the step of the sample "
                "that completes them"
            )
        end = self._head + rel + g.size
        if end > self._acc.shape[0]:
            self._compact(end - self._head)
        i = self._head + rel
        self._acc[i : i + g.size] += np.multiply.outer(g, v)

    def _compact(self, needed: int) -> None:
        live = self._acc[self._head :]
        size = max(self._acc.shape[0], 2 * needed)
        acc = np.zeros((size, self._C))
        acc[: live.shape[0]] = live
        self._acc = acc
        self._head = 0

    def step(self, coefficients: Iterable[Coefficient] = ()) -> np.ndarray:
        """
        Add coefficients, then return the next output sample.

        Parameters
        ----------
        coefficients : iterable of Coefficient
            Records (e.g. the list :meth:`AnalysisFilterbank.step` returned for this
            sample), each with ``level``, ``kind``, ``translation_index``, ``values``.

        Returns
        -------
        numpy.ndarray
            ``y[next_sample_index]``, shape ``(C,)``.
        """
        for r in coefficients:
            self.add(r.level, r.kind, r.translation_index, r.values)
        out = self._acc[self._head].copy()
        self._acc[self._head] = 0.0
        self._head += 1
        self._next += 1
        if self._head * 2 >= self._acc.shape[0]:
            self._compact(self._acc.shape[0] - self._head)
        return out
