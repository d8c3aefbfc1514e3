"""
Causal multi-level analysis filterbank, streaming and block (figure 4.3, eq. 4.12-4.15).

Each level filters its input with :math:`h_0` and :math:`h_1` and keeps every second
output (eq. 4.8, 4.13); the low-pass output feeds the next level (eq. 4.14-4.15). The
filtering and down-sampling are evaluated in polyphase form (eq. 4.22-4.28): only the
outputs that are kept are ever computed, each as one inner product of the filter with the
last ``L`` input samples of that level, as soon as its last input sample has arrived.

Relation to PyWavelets
----------------------
Level ``j``, translation index ``m`` (both forms, started at sample index 0)::

    detail[j][m]  == pywt.wavedec(x, wavelet, mode="zero", level=J)[J - j + 1][m]
    approximation[m] == pywt.wavedec(x, wavelet, mode="zero", level=J)[0][m]

for ``0 <= m < N // 2**j`` (``N`` samples given so far), and at level 1 the same holds
for ``pywt.dwt(x, wavelet, mode="zero")``. That is, the signal is taken as zero before
its first sample (``mode="zero"``); the recursion is
``a_j[m] = sum_k dec_lo[k] a_{j-1}[2m + 1 - k]`` with ``a_0 = x``, which is PyWavelets'
own alignment. The causal filterbank returns exactly the leading ``N // 2**j``
coefficients of each level, those whose support ends by sample ``N - 1``. PyWavelets
returns more (``(N_{j-1} + L - 1) // 2`` at level ``j``, with ``N_0 = N``); the extra
trailing ones depend on the zero padding after the last sample and have no causal
counterpart. For Haar (``L = 2``) the two agree except for an odd final sample. Other
PyWavelets modes (``symmetric``, ``periodization``...) differ from this only in the
coefficients whose support reaches past either end.

Timing of each level is in :mod:`amb_wavelet.levels`: coefficient ``m`` of level ``j``
is completed and emitted by sample ``2**j (m + 1) - 1``; its support is
``(2**j - 1)(L - 1) + 1`` samples ending there. Start-up coefficients whose support
begins before the reset sample are computed with zeros for the missing samples and are
flagged ``settled=False``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from amb_wavelet.errors import SampleIndexError
from amb_wavelet.filters import FilterSet, get_filters
from amb_wavelet.levels import check_level, support_length

__all__ = [
    "APPROXIMATION",
    "DETAIL",
    "AnalysisFilterbank",
    "Coefficient",
    "Decomposition",
    "analyze_block",
]

DETAIL = "detail"
APPROXIMATION = "approximation"


class Coefficient(NamedTuple):
    """
    One completed wavelet coefficient for all channels (what the node publishes).

    Attributes
    ----------
    level : int
        Filterbank level ``j`` (1 = finest).
    kind : str
        ``"detail"`` (wavelet, :math:`h_1` branch) or ``"approximation"`` (scaling,
        :math:`h_0` branch, deepest level only).
    translation_index : int
        ``m``: the coefficient is completed by sample ``2**level (m + 1) - 1``.
    first_sample_index, last_sample_index : int
        First and last sample index of the support (first may be negative at start-up).
    values : numpy.ndarray
        Coefficient of each channel, shape ``(C,)``, in the channel unit (m for
        displacement) times the orthonormal scaling of eq. 4.6 (sum of squares of the
        coefficients equals the signal energy, Parseval).
    settled : bool
        True if the whole support lies at or after the last reset, i.e. no start-up
        zeros entered the coefficient.
    """

    level: int
    kind: str
    translation_index: int
    first_sample_index: int
    last_sample_index: int
    values: np.ndarray
    settled: bool


@dataclass(frozen=True)
class Decomposition:
    """
    Coefficients from a block of samples.

    Attributes
    ----------
    wavelet : str
        PyWavelets name.
    details : tuple of numpy.ndarray
        ``details[j - 1]`` holds level ``j``, shape ``(M_j, C)`` (or ``(M_j,)`` for a 1-D
        input), rows in translation order.
    approximation : numpy.ndarray
        Deepest-level approximation, shape ``(M_J, C)``.
    translation_start : tuple of int
        Translation index of row 0 of each level (0 for a block started at index 0).
    """

    wavelet: str
    details: tuple[np.ndarray, ...]
    approximation: np.ndarray
    translation_start: tuple[int, ...]

    @property
    def level(self) -> int:
        """Number of levels ``J``."""
        return len(self.details)


class AnalysisFilterbank:
    """
    Streaming causal analysis filterbank for ``n_channels`` channels.

    Parameters
    ----------
    wavelet : str
        Orthogonal PyWavelets name (see :func:`amb_wavelet.filters.get_filters`).
    level : int
        Number of levels ``J >= 1``; details of levels ``1 .. J`` and the level-``J``
        approximation are produced.
    n_channels : int
        Channels per sample ``C``.
    start_sample_index : int
        Absolute index of the first sample after construction (see :meth:`reset`).

    Notes
    -----
    :meth:`step` (one sample) and :meth:`process_block` (many) share one state and give
    the same numbers; calls may be mixed. The dyadic grid is anchored at absolute sample
    index 0, so translation indices and support indices are absolute and stay aligned
    with revolutions after a reset at any index.
    """

    def __init__(
        self, wavelet: str, level: int, n_channels: int, start_sample_index: int = 0
    ) -> None:
        self._filters: FilterSet = get_filters(wavelet)
        self._level = check_level(level)
        if isinstance(n_channels, bool) or not isinstance(n_channels, int) or n_channels < 1:
            raise ValueError(f"n_channels must be an int >= 1, got {n_channels!r}")
        self._C = n_channels
        L = self._filters.length
        self._L = L
        # rows: h0 and h1 reversed, so that F @ window = sum_k h[k] x[n - k] (eq. 4.8)
        self._F = np.ascontiguousarray(
            np.stack([self._filters.dec_lo[::-1], self._filters.dec_hi[::-1]])
        )
        self._h0 = self._filters.dec_lo
        self._h1 = self._filters.dec_hi
        self._span = [support_length(j, L) - 1 for j in range(1, self._level + 1)]
        # one doubled ring buffer per level: sample in slot s is stored at s and s + L
        self._bufs = np.zeros((self._level, 2 * L, n_channels))
        self._pos = [L - 1] * self._level
        self.reset(start_sample_index)

    @property
    def wavelet(self) -> str:
        """PyWavelets name."""
        return self._filters.wavelet

    @property
    def level(self) -> int:
        """Number of levels ``J``."""
        return self._level

    @property
    def n_channels(self) -> int:
        """Channels per sample ``C``."""
        return self._C

    @property
    def filters(self) -> FilterSet:
        """Filters in use."""
        return self._filters

    @property
    def next_sample_index(self) -> int:
        """Index the next sample must carry."""
        return self._next

    @property
    def start_sample_index(self) -> int:
        """Index of the first sample after the last reset."""
        return self._start

    def reset(self, start_sample_index: int = 0) -> None:
        """
        Clear the filter state; the signal is taken as zero before ``start_sample_index``.

        Parameters
        ----------
        start_sample_index : int
            Absolute index of the next sample (>= 0).
        """
        if isinstance(start_sample_index, bool) or int(start_sample_index) != start_sample_index:
            raise ValueError(f"start_sample_index must be an int, got {start_sample_index!r}")
        if start_sample_index < 0:
            raise ValueError(f"start_sample_index must be >= 0, got {start_sample_index}")
        self._bufs[...] = 0.0
        self._pos = [self._L - 1] * self._level
        self._start = int(start_sample_index)
        self._next = int(start_sample_index)

    def step(self, sample: ArrayLike, sample_index: int | None = None) -> list[Coefficient]:
        """
        Take one sample and return the coefficients it completes.

        Parameters
        ----------
        sample : array_like
            Shape ``(C,)``, one value per channel (channel units, e.g. m).
        sample_index : int, optional
            Index of this sample; if given it must equal :attr:`next_sample_index`.

        Returns
        -------
        list of Coefficient
            Details from the finest completed level upwards, then the approximation if
            level ``J`` completed; empty for even sample indices.

        Raises
        ------
        SampleIndexError
            If ``sample_index`` is not the expected one (state unchanged).
        ValueError
            If ``sample`` has the wrong shape.
        """
        n = self._next
        if sample_index is not None and sample_index != n:
            raise SampleIndexError(n, sample_index)
        v = np.asarray(sample, dtype=float)
        if v.shape != (self._C,):
            raise ValueError(
                f"sample must have shape ({self._C},), got {v.shape}; one value per channel"
            )
        self._next = n + 1
        L = self._L
        bufs = self._bufs
        pos = self._pos
        F = self._F
        out: list[Coefficient] = []
        idx = n
        for j in range(self._level):
            p = pos[j] + 1
            if p == L:
                p = 0
            pos[j] = p
            buf = bufs[j]
            buf[p] = v
            buf[p + L] = v
            if not idx & 1:
                return out
            ah = F @ buf[p + 1 : p + 1 + L]
            idx >>= 1
            first = n - self._span[j]
            out.append(Coefficient(j + 1, DETAIL, idx, first, n, ah[1], first >= self._start))
            v = ah[0]
        out.append(Coefficient(self._level, APPROXIMATION, idx, first, n, v, first >= self._start))
        return out

    def process_block(self, x: ArrayLike) -> Decomposition:
        """
        Take a block of consecutive samples and return the coefficients they complete.

        Parameters
        ----------
        x : array_like
            Shape ``(N, C)``; row ``i`` is sample ``next_sample_index + i``. A 1-D array
            is accepted when ``C == 1`` (outputs are then 1-D).

        Returns
        -------
        Decomposition
            The same numbers :meth:`step` would have returned sample by sample.
        """
        a = np.asarray(x, dtype=float)
        squeeze = a.ndim == 1 and self._C == 1
        if squeeze:
            a = a[:, None]
        if a.ndim != 2 or a.shape[1] != self._C:
            raise ValueError(
                f"block must have shape (N, {self._C}) (one row per sample), got {a.shape}"
            )
        L = self._L
        h0, h1 = self._h0, self._h1
        i0 = self._next
        self._next = i0 + a.shape[0]
        details: list[np.ndarray] = []
        starts: list[int] = []
        cur = a
        for j in range(self._level):
            buf = self._bufs[j]
            p = self._pos[j]
            ext = np.concatenate([buf[p + 2 : p + 1 + L], cur])  # last L-1 inputs + new
            n_in = cur.shape[0]
            M = ((i0 + n_in) >> 1) - (i0 >> 1)  # odd input indices in [i0, i0 + n_in)
            r = (i0 | 1) - i0 + L - 1  # row of ext holding the first odd input index
            lo = np.zeros((M, self._C))
            hi = np.zeros((M, self._C))
            if M:
                tmp = np.empty((M, self._C))
                for k in range(L):  # polyphase: only the kept outputs (eq. 4.28)
                    seg = ext[r - k : r - k + 2 * M - 1 : 2]
                    np.multiply(seg, h0[k], out=tmp)
                    lo += tmp
                    np.multiply(seg, h1[k], out=tmp)
                    hi += tmp
            if n_in:
                tail = ext[-L:]
                buf[:L] = tail
                buf[L:] = tail
                self._pos[j] = L - 1
            details.append(hi[:, 0] if squeeze else hi)
            starts.append(i0 >> 1)
            cur = lo
            i0 >>= 1
        approx = cur[:, 0] if squeeze else cur
        return Decomposition(self.wavelet, tuple(details), approx, tuple(starts))


def analyze_block(x: ArrayLike, wavelet: str, level: int) -> Decomposition:
    """
    Causal analysis of a whole record started at sample index 0.

    Parameters
    ----------
    x : array_like
        Shape ``(N,)`` or ``(N, C)`` (samples along axis 0).
    wavelet : str
        Orthogonal PyWavelets name.
    level : int
        Number of levels ``J``.

    Returns
    -------
    Decomposition
        ``details[j - 1]`` has ``N // 2**j`` rows and equals the leading rows of
        ``pywt.wavedec(x, wavelet, mode="zero", level=J, axis=0)`` (see module notes).
    """
    a = np.asarray(x, dtype=float)
    if a.ndim not in (1, 2):
        raise ValueError(f"x must be 1-D (N,) or 2-D (N, C), got shape {a.shape}")
    bank = AnalysisFilterbank(wavelet, level, 1 if a.ndim == 1 else a.shape[1])
    return bank.process_block(a)
