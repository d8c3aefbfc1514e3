"""
Prescribed transient responses alpha_{p,q}(z) of the wavelet transient controller.

The controller of thesis chapter 8 is designed so that, after a step change in the
wavelet coefficients of the input disturbance, the measured coefficients follow
``Q(z) = alpha(z) G(z) B_u`` (eq. 8.3): ``c_k``, the k-th term of the series of
``alpha`` (eq. 8.7), is the fraction of the uncontrolled response that remains after k
control periods.

Representation
--------------
``alpha`` is a rational function of ``z^-1`` held as two coefficient arrays in
ascending powers of ``z^-1``: ``alpha(z) = num(z^-1) / den(z^-1)`` with ``num[0] == 0``
(``alpha`` is strictly proper: nothing is asked of the period of the step itself, as
in eq. 8.7 where the series starts at k = 1) and ``num[1] == c_1 != 0`` (otherwise the
controller of eq. 8.10 is not causal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from amb_controller.errors import ControllerValueError


@dataclass(frozen=True)
class PrescribedResponse:
    """
    Prescribed transient response ``alpha(z) = num(z^-1) / den(z^-1)`` (eq. 8.6-8.7).

    Parameters
    ----------
    num : numpy.ndarray
        Numerator coefficients in ascending powers of ``z^-1``; ``num[0]`` must be 0 and
        ``num[1]`` (= ``c_1``) non-zero. Dimensionless.
    den : numpy.ndarray
        Denominator coefficients in ascending powers of ``z^-1``, ``den[0] != 0``.
    label : str
        Human-readable description (for reports and the model file).

    """

    num: np.ndarray
    den: np.ndarray
    label: str = "custom"

    def __post_init__(self) -> None:
        num = np.atleast_1d(np.asarray(self.num, dtype=float))
        den = np.atleast_1d(np.asarray(self.den, dtype=float))
        if (
            num.ndim != 1
            or den.ndim != 1
            or not (np.all(np.isfinite(num)) and np.all(np.isfinite(den)))
        ):
            raise ControllerValueError(
                "alpha num/den must be finite 1-D coefficient arrays in powers of z^-1, got "
                f"num={self.num!r}, den={self.den!r}"
            )
        if num.size < 2 or num[0] != 0.0 or num[1] == 0.0:
            raise ControllerValueError(
                "alpha must be strictly proper with c_1 != 0: expected num[0] == 0 and "
                f"num[1] != 0, got num={num.tolist()}; a zero c_1 makes the controller of "
                "eq. 8.10 non-causal (start the series at the first period)"
            )
        if den[0] == 0.0:
            raise ControllerValueError(f"alpha den[0] must be non-zero, got den={den.tolist()}")
        object.__setattr__(self, "num", num / den[0])
        object.__setattr__(self, "den", den / den[0])

    # ----------------------------------------------------------------- constructors
    @classmethod
    def exponential(cls, w: float, v: float) -> PrescribedResponse:
        """
        Exponential decay ``alpha(z) = w / (z - v)`` (eq. 8.6), so ``c_k = w v^(k-1)``.

        Parameters
        ----------
        w : float
            Gain, ``w > 0`` (thesis range 0 <= w < 1; w = 0 asks for an infinite gain).
        v : float
            Decay ratio per control period, ``0 <= v < 1``.

        Returns
        -------
        PrescribedResponse

        """
        if not (np.isfinite(w) and w > 0.0):
            raise ControllerValueError(
                f"exponential response needs w > 0 (thesis eq. 8.6: 0 <= w < 1), got w={w}; "
                "w = 0 would demand an infinite controller gain"
            )
        if not (np.isfinite(v) and 0.0 <= v < 1.0):
            raise ControllerValueError(
                f"exponential response needs 0 <= v < 1 (eq. 8.6), got v={v}; v >= 1 never decays"
            )
        return cls(np.array([0.0, w]), np.array([1.0, -v]), label=f"exponential(w={w:g}, v={v:g})")

    @classmethod
    def linear_decay(cls, rate: float) -> PrescribedResponse:
        """
        Linear decay ``c_k = max(0, 1 - rate * k)``, k >= 1 (thesis section 8.5).

        The thesis gives only "a linear decay rate of 0.2 per time step" (fig. 8.17) and a
        limit of 0.31 per step; we read it, by analogy with eq. 8.6 where ``w = v`` gives
        ``c_k = v^k``, as the remaining fraction falling by ``rate`` every period.

        Parameters
        ----------
        rate : float
            Decay per control period, ``0 < rate < 1``.

        Returns
        -------
        PrescribedResponse

        """
        if not (np.isfinite(rate) and 0.0 < rate < 1.0):
            raise ControllerValueError(
                f"linear decay rate must lie in (0, 1) per period, got {rate}"
            )
        k = np.arange(1, int(np.ceil(1.0 / rate)) + 1)
        c = np.clip(1.0 - rate * k, 0.0, None)
        c = np.trim_zeros(c, "b")
        return cls(np.concatenate(([0.0], c)), np.array([1.0]), label=f"linear(rate={rate:g})")

    @classmethod
    def from_series(cls, c) -> PrescribedResponse:
        """
        Finite series ``alpha(z) = sum_k c_k z^-k``, k = 1..K (eq. 8.7).

        Parameters
        ----------
        c : array_like
            ``c_1 .. c_K``, the fraction of the uncontrolled response wanted after each
            period; ``c_1 != 0``.

        Returns
        -------
        PrescribedResponse

        """
        c = np.atleast_1d(np.asarray(c, dtype=float))
        return cls(np.concatenate(([0.0], c)), np.array([1.0]), label=f"series({c.size} terms)")

    # ----------------------------------------------------------------- properties
    def series(self, n_terms: int) -> np.ndarray:
        """
        Return ``c_1 .. c_n`` of eq. 8.7 (the impulse response of ``alpha``).

        Parameters
        ----------
        n_terms : int
            Number of terms.

        Returns
        -------
        numpy.ndarray
            Shape ``(n_terms,)``.

        """
        impulse = np.zeros(n_terms + 1)
        impulse[0] = 1.0
        return signal.lfilter(self.num, self.den, impulse)[1:]

    def evaluate(self, z) -> np.ndarray:
        """
        Evaluate ``alpha(z)`` at complex ``z``.

        Parameters
        ----------
        z : array_like of complex
            Points of the z-plane.

        Returns
        -------
        numpy.ndarray of complex

        """
        x = 1.0 / np.asarray(z, dtype=complex)
        return np.polyval(self.num[::-1], x) / np.polyval(self.den[::-1], x)

    def poles(self) -> np.ndarray:
        """Return the poles of ``alpha`` in the z-plane (must lie inside the unit circle)."""
        return _zinv_roots(self.den)

    def beta(self) -> tuple[np.ndarray, np.ndarray]:
        """
        Return ``beta(z) = 1 / (alpha(z) (z - 1)) - 1`` as (num, den) in powers of ``z^-1``.

        This is the prescribed-response factor of the controller of eq. 8.5/8.10. With
        ``alpha(z)(z - 1) = a(z^-1)(1 - z^-1) / den(z^-1)`` where ``a = num[1:]``,
        ``beta = (den - a (1 - z^-1)) / (a (1 - z^-1))``: a causal filter with a pole at
        z = 1 (integral action) and poles at the zeros of ``a``.

        Returns
        -------
        num, den : numpy.ndarray
            Equal-length coefficient arrays, ``den[0] == 1``.

        """
        a = self.num[1:]
        den_beta = np.convolve(a, [1.0, -1.0])
        num_beta = _padd(self.den, -den_beta)
        n = max(num_beta.size, den_beta.size)
        num_beta = np.pad(num_beta, (0, n - num_beta.size))
        den_beta = np.pad(den_beta, (0, n - den_beta.size))
        return num_beta / den_beta[0], den_beta / den_beta[0]

    def controller_poles(self) -> np.ndarray:
        """Return the poles of ``beta`` other than z = 1: the zeros of ``alpha``."""
        return _zinv_roots(self.num[1:])


def _padd(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Add two ascending coefficient arrays of different lengths."""
    n = max(p.size, q.size)
    return np.pad(p, (0, n - p.size)) + np.pad(q, (0, n - q.size))


def _zinv_roots(p: np.ndarray) -> np.ndarray:
    """
    Return the z-plane roots of ``sum_j p[j] z^-j``.

    ``sum_j p_j z^-j = z^-L sum_j p_j z^(L-j)``, so the roots in z are those of the
    polynomial with descending coefficients ``p``; leading zeros of ``p`` are pure delays
    and trailing zeros only lower the degree, so both are trimmed first.
    """
    p = np.trim_zeros(np.asarray(p, dtype=float), "fb")
    if p.size <= 1:
        return np.zeros(0, dtype=complex)
    return np.roots(p).astype(complex)
