r"""
Period-sampled wavelet coefficients x_{p,q}(kT) and period averages x^0(kT) (eq. 6.1-6.4).

The control period ``T`` is one revolution, ``samples_per_rev = 2**R`` samples. Within
period ``k`` the signal is written (eq. 6.2-6.3) as its average :math:`x^0(kT)` plus
wavelets at levels ``p = 1 .. R`` and translations ``q = 1 .. 2**(p - 1)``:

* ``p`` is the thesis level of chapters 7-8: ``p = 1`` at 1 x running speed
  (:math:`x_{1,1}`), ``p = 2`` at 2 x, ``p = 3`` at 4 x; filterbank level
  ``j = R - p + 1`` (:mod:`amb_wavelet.levels`).
* ``q`` numbers, from 1 and in time order, the level-``j`` coefficients completed inside
  the period: translation index ``m = k 2**(p-1) + q - 1``, completed by sample
  ``k samples_per_rev + q 2**j - 1``.
* ``period_index`` ``k`` counts from 0 and covers samples
  ``k samples_per_rev .. (k + 1) samples_per_rev - 1``; it is the thesis's
  :math:`x_{p,q}((k + 1)T)` (eq. 6.3 counts periods from 1 and stamps the period ending
  at ``kT``).

Decisions (thesis ambiguities):

* Scaling: the coefficients are the orthonormal discrete ones of the filterbank (eq. 4.6:
  Haar level ``j`` weights are :math:`\pm 2^{-j/2}`), not eq. 6.1's
  :math:`|p|^{-1/2}\int` (which is undefined for ``p = 0`` and mixes continuous time with
  levels). With this scaling eq. 6.2 holds exactly in discrete time for Haar:
  ``x[n] = x0 + sum_{p,q} x_{p,q} psi_{p,q}[n]`` with unit-energy :math:`\psi_{p,q}`.
* Average: :math:`x^0(kT)` is the arithmetic mean of the period's samples, for every
  wavelet (eq. 6.2: "the average value over [0, T]"). For Haar it equals the level-``R``
  approximation divided by :math:`2^{R/2}`.
* Other orthogonal wavelets: their supports are longer than ``2**j`` samples, so a
  coefficient completed in period ``k`` also depends on earlier samples (up to
  ``(2**j - 1)(L - 2)`` of them before the period); eq. 6.2 is then not a per-period
  identity, but ``x_{p,q}(kT)`` remains the coefficient that completes inside the
  period, as a causal controller sees it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from amb_wavelet.analysis import DETAIL, AnalysisFilterbank
from amb_wavelet.errors import LevelError
from amb_wavelet.levels import level_from_thesis_p, revolution_level

__all__ = ["PeriodCoefficients", "PeriodSampler", "period_coefficients", "period_position"]


def period_position(
    level: int, translation_index: int, samples_per_rev: int
) -> tuple[int, int, int]:
    """
    Map a filterbank coefficient to ``(period_index, p, q)``.

    Parameters
    ----------
    level : int
        Filterbank level ``j``, ``1 <= j <= log2(samples_per_rev)``.
    translation_index : int
        ``m`` (>= 0).
    samples_per_rev : int
        Samples per revolution (power of two).

    Returns
    -------
    tuple of int
        ``(k, p, q)`` with ``p = R - j + 1``, ``k = m // 2**(p - 1)``,
        ``q = m % 2**(p - 1) + 1``.

    Raises
    ------
    LevelError
        For ``level > log2(samples_per_rev)`` (below 1 x: part of the average, not of
        eq. 6.2) or ``level < 1``.
    """
    r = revolution_level(samples_per_rev)
    if not 1 <= level <= r:
        raise LevelError(
            f"level {level} has no period-sampled index: expected 1 <= level <= "
            f"log2(samples_per_rev) = {r}; slower levels belong to the period average x0"
        )
    per = 2 ** (r - level)
    return int(translation_index) // per, r - level + 1, int(translation_index) % per + 1


@dataclass(frozen=True)
class PeriodCoefficients:
    """
    Period-sampled coefficients of one period (streaming) or many (block).

    Attributes
    ----------
    period_index : numpy.ndarray
        Period indices ``k``, shape ``(K,)``.
    average : numpy.ndarray
        :math:`x^0`, shape ``(K, C)`` (channel unit).
    coefficients : dict of int to numpy.ndarray
        ``coefficients[p]`` has shape ``(K, 2**(p - 1), C)``; ``[:, q - 1]`` is
        :math:`x_{p,q}`.
    settled : numpy.ndarray
        Shape ``(K,)``, True if no start-up zeros entered any value of the period.
    """

    period_index: np.ndarray
    average: np.ndarray
    coefficients: dict[int, np.ndarray]
    settled: np.ndarray


class PeriodSampler:
    """
    Streaming period-sampled coefficients: one sample in, one period out at its end.

    Parameters
    ----------
    wavelet : str
        Orthogonal PyWavelets name.
    samples_per_rev : int
        Samples per revolution ``2**R`` (the control period).
    n_channels : int
        Channels ``C``.
    p_max : int, optional
        Deepest thesis level kept (``1 .. R``); default ``R``.
    start_sample_index : int
        Absolute index of the next sample; periods are aligned to multiples of
        ``samples_per_rev``.
    """

    def __init__(
        self,
        wavelet: str,
        samples_per_rev: int,
        n_channels: int,
        p_max: int | None = None,
        start_sample_index: int = 0,
    ) -> None:
        self._R = revolution_level(samples_per_rev)
        self._N = int(samples_per_rev)
        self._p_max = self._R if p_max is None else int(p_max)
        level_from_thesis_p(self._p_max, samples_per_rev)  # validates p_max
        self._C = int(n_channels)
        self._bank = AnalysisFilterbank(wavelet, self._R, self._C, start_sample_index)
        self._j_min = self._R - self._p_max + 1
        self.reset(start_sample_index)

    @property
    def filterbank(self) -> AnalysisFilterbank:
        """The underlying analysis filterbank (levels ``1 .. R``)."""
        return self._bank

    def reset(self, start_sample_index: int = 0) -> None:
        """
        Clear all state; the signal is taken as zero before ``start_sample_index``.

        Parameters
        ----------
        start_sample_index : int
            Absolute index of the next sample.
        """
        self._bank.reset(start_sample_index)
        self._coef = {p: np.zeros((2 ** (p - 1), self._C)) for p in range(1, self._p_max + 1)}
        self._sum = np.zeros(self._C)
        self._count = start_sample_index % self._N
        self._settled = self._count == 0

    def step(self, sample: ArrayLike, sample_index: int | None = None) -> PeriodCoefficients | None:
        """
        Take one sample; at the last sample of a period return that period.

        Parameters
        ----------
        sample : array_like
            Shape ``(C,)``.
        sample_index : int, optional
            Checked against the expected index (see :class:`AnalysisFilterbank`).

        Returns
        -------
        PeriodCoefficients or None
            With ``K = 1`` at the end of a period, else None.
        """
        n = self._bank.next_sample_index
        records = self._bank.step(sample, sample_index)
        self._sum += np.asarray(sample, dtype=float)
        self._count += 1
        for r in records:
            if r.kind == DETAIL and r.level >= self._j_min:
                _, p, q = period_position(r.level, r.translation_index, self._N)
                self._coef[p][q - 1] = r.values
                self._settled &= r.settled
        if self._count < self._N:
            return None
        out = PeriodCoefficients(
            period_index=np.array([n // self._N]),
            average=(self._sum / self._N)[None, :],
            coefficients={p: c[None].copy() for p, c in self._coef.items()},
            settled=np.array([self._settled]),
        )
        self._sum = np.zeros(self._C)
        self._count = 0
        self._settled = True
        return out


def period_coefficients(
    x: ArrayLike, wavelet: str, samples_per_rev: int, p_max: int | None = None
) -> PeriodCoefficients:
    """
    Period-sampled coefficients of a record started at sample index 0 (block form).

    Parameters
    ----------
    x : array_like
        Shape ``(N, C)`` or ``(N,)``; only the ``N // samples_per_rev`` complete periods
        are returned.
    wavelet : str
        Orthogonal PyWavelets name.
    samples_per_rev : int
        Samples per revolution ``2**R``.
    p_max : int, optional
        Deepest thesis level kept, default ``R``.

    Returns
    -------
    PeriodCoefficients
        ``K = N // samples_per_rev`` periods; same numbers as :class:`PeriodSampler`.
    """
    a = np.asarray(x, dtype=float)
    squeeze = a.ndim == 1
    if squeeze:
        a = a[:, None]
    if a.ndim != 2:
        raise ValueError(f"x must have shape (N,) or (N, C), got {np.shape(x)}")
    R = revolution_level(samples_per_rev)
    p_max = R if p_max is None else int(p_max)
    level_from_thesis_p(p_max, samples_per_rev)
    K = a.shape[0] // samples_per_rev
    a = a[: K * samples_per_rev]
    bank = AnalysisFilterbank(wavelet, R, a.shape[1])
    dec = bank.process_block(a)
    L = bank.filters.length
    coefs = {}
    settled = np.ones(K, dtype=bool)
    for p in range(1, p_max + 1):
        j = R - p + 1
        d = dec.details[j - 1]  # (K * 2**(p-1), C), m = k 2**(p-1) + q - 1
        coefs[p] = d.reshape(K, 2 ** (p - 1), a.shape[1])
        # coefficient m is settled when 2**j (m + 1) - 1 - (2**j - 1)(L - 1) >= 0
        m = np.arange(d.shape[0])
        ok = 2**j * (m + 1) - 1 - (2**j - 1) * (L - 1) >= 0
        settled &= ok.reshape(K, -1).all(axis=1)
    avg = a.reshape(K, samples_per_rev, a.shape[1]).mean(axis=1)
    if squeeze:
        avg = avg[:, 0]
        coefs = {p: c[..., 0] for p, c in coefs.items()}
    return PeriodCoefficients(np.arange(K), avg, coefs, settled)
