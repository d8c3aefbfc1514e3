r"""
Heisenberg and balanced uncertainty of wavelet filters (thesis section 4.5, Table 4.1).

From the ``L`` coefficients :math:`h_n` of the low-pass (scaling) analysis filter:

.. math::

    (\Delta\omega)^2 = \frac{\pi^2}{3} + 4 \sum_{n=0}^{L-2} \sum_{m=n+1}^{L-1}
        \frac{(-1)^{m-n}}{P (m-n)^2} h_m h_n  \quad (4.32), \qquad
    P = \sum_n h_n^2  \quad (4.33)

.. math::

    (\Delta t)^2 = \sum_{n=0}^{L-1} (n - \alpha)^2 h_n^2 \quad (4.34), \qquad
    \alpha = \frac{\sum n h_n}{\sum h_n} \quad (4.35), \qquad
    M(k) = (\Delta\omega)^2 + k (\Delta t)^2 \quad (4.36)

Decisions (thesis typos), checked against Table 4.1:

* Eq. 4.33 prints the sum for ``P`` up to ``L - 2``; with that bound the Haar filter gives
  :math:`(\Delta\omega)^2 < 0`. The text says ``P = 1`` for orthogonal filters, which
  is the sum over all ``L`` taps; that sum reproduces Table 4.1 and is used here.
* The filter is the low-pass :math:`h_0` (``dec_lo``): the high-pass filter gives
  ``1.136 -> 2.30`` for Haar. Reversing the filter changes neither measure.

Units: :math:`\Delta t` in samples and :math:`\Delta\omega` in rad/sample of the
filter's own rate (the thesis's unit sample interval). At level ``j`` of a bank sampled at
``fs`` (Hz) the physical values are ``delta_t * 2**j / fs`` (s) and
``delta_omega * fs / 2**j`` (rad/s); the product is scale free.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike

from amb_wavelet.filters import get_filters

__all__ = ["Uncertainty", "filter_uncertainty", "uncertainty"]


@dataclass(frozen=True)
class Uncertainty:
    r"""
    Uncertainty measures of one filter (one row of Table 4.1).

    Attributes
    ----------
    wavelet : str
        PyWavelets name (``""`` for a bare filter).
    delta_omega : float
        Bandwidth :math:`\Delta\omega` (rad/sample), eq. 4.32.
    delta_t : float
        Time dispersion :math:`\Delta t` (samples), eq. 4.34.
    product : float
        :math:`\Delta\omega \Delta t` (>= 1/2, eq. 4.29).
    balanced : float
        :math:`M(k)`, eq. 4.36.
    k : float
        Weight of the time dispersion in ``balanced``.
    """

    wavelet: str
    delta_omega: float
    delta_t: float
    product: float
    balanced: float
    k: float

    def as_dict(self) -> dict:
        """Plain dict (for JSON)."""
        return asdict(self)


def filter_uncertainty(h: ArrayLike, k: float = 1.0, wavelet: str = "") -> Uncertainty:
    r"""
    Uncertainty measures from low-pass filter coefficients (eq. 4.32-4.36).

    Parameters
    ----------
    h : array_like
        Low-pass filter coefficients :math:`h_0 .. h_{L-1}`, ``L >= 2``, nonzero sum.
    k : float
        Weight of :math:`(\Delta t)^2` in :math:`M(k)` (>= 0).
    wavelet : str
        Name stored in the result.

    Returns
    -------
    Uncertainty
    """
    hh = np.asarray(h, dtype=float)
    if hh.ndim != 1 or hh.size < 2:
        raise ValueError(f"h must be a 1-D filter with >= 2 taps, got shape {hh.shape}")
    if abs(hh.sum()) < 1e-12:
        raise ValueError(
            "h sums to zero: expected the low-pass (scaling) filter, got a high-pass one; "
            "pass FilterSet.dec_lo"
        )
    if not k >= 0:
        raise ValueError(f"k must be >= 0, got {k!r}")
    L = hh.size
    n = np.arange(L)
    P = float(np.sum(hh**2))  # eq. 4.33 over all L taps (see module notes)
    lag = n[None, :] - n[:, None]  # m - n for row n, column m
    upper = lag > 0
    terms = np.where(upper, (-1.0) ** lag / (P * np.where(upper, lag, 1) ** 2), 0.0)
    dw2 = np.pi**2 / 3 + 4 * float(hh @ terms @ hh)
    alpha = float(n @ hh / hh.sum())
    dt2 = float(np.sum((n - alpha) ** 2 * hh**2))
    dw, dt = float(np.sqrt(dw2)), float(np.sqrt(dt2))
    return Uncertainty(wavelet, dw, dt, dw * dt, dw2 + k * dt2, float(k))


def uncertainty(wavelet: str, k: float = 1.0) -> Uncertainty:
    """
    Uncertainty measures of an orthogonal wavelet (Table 4.1 for ``k = 1``).

    Parameters
    ----------
    wavelet : str
        Orthogonal PyWavelets name.
    k : float
        Weight in :math:`M(k)` (eq. 4.36).

    Returns
    -------
    Uncertainty
    """
    f = get_filters(wavelet)
    return filter_uncertainty(f.dec_lo, k, f.wavelet)
