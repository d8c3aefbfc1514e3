"""
Control coefficients -> force samples of the target period, with saturation.

Synthesis: ``f[c, n] = sum_i u_i weights[i, c, n]`` over the period (the control basis of
:mod:`amb_controller.basis`: PyWavelets periodised orthonormal wavelets of one period,
even and odd channels). For Haar these are exactly the basis functions of
:func:`amb_wavelet.synthesis.basis_function` placed inside the period; longer wavelets
are wrapped round the period so that each command stays inside its target period, as
``ControlCommand.force`` requires (the causal synthesis filterbank of
:mod:`amb_wavelet.synthesis` would spread them over later periods with its delay
``(2^J - 1)(L - 1)``).

Saturation: the wavelet force of each axis is limited to ``limit[axis]`` N, itself at
most the bearing capacity (``amb.force_limit`` of ``config/rig.yaml``, read by the
caller). An axis whose peak exceeds its limit has all its coefficients scaled by
``limit / peak`` (the waveform keeps its shape and phase); the caller holds the
controller state while saturated (anti-windup, :mod:`amb_controller.supervisor`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from amb_controller.basis import BasisSet
from amb_controller.errors import ControllerValueError, ShapeError


def synthesize(coefficients: np.ndarray, basis: BasisSet) -> np.ndarray:
    """
    Return the waveform of a coefficient vector over one period.

    Parameters
    ----------
    coefficients : numpy.ndarray
        Shape ``(basis.n_coefficients,)``.
    basis : BasisSet
        Control basis (or any block basis, e.g. to reconstruct the predicted steady state
        of section 7.4.1 with the residue set to zero).

    Returns
    -------
    numpy.ndarray
        Shape ``(basis.n_channels, length)``; N for forces.

    """
    coefficients = np.asarray(coefficients, dtype=float)
    if coefficients.shape != (basis.n_coefficients,):
        raise ShapeError(
            f"coefficients must have shape ({basis.n_coefficients},), got {coefficients.shape}"
        )
    return np.einsum("i,icn->cn", coefficients, basis.weights)


@dataclass(frozen=True)
class SaturationResult:
    """
    Output of :meth:`ForceLimiter.apply`.

    Attributes
    ----------
    coefficients : numpy.ndarray
        Scaled control coefficients.
    force : numpy.ndarray
        Force samples, shape ``(n_axes, samples_per_period)`` (N).
    saturated : numpy.ndarray of bool
        Per axis, True if it was scaled.
    peak : numpy.ndarray
        Per axis, the peak force after scaling (N).

    """

    coefficients: np.ndarray
    force: np.ndarray
    saturated: np.ndarray
    peak: np.ndarray


class ForceLimiter:
    """
    Synthesis with a per-axis wavelet force limit.

    Parameters
    ----------
    basis : BasisSet
        Control basis (one axis per coefficient).
    limit : float or array_like
        Wavelet force limit per axis in N (> 0).
    capacity : float
        Bearing capacity in N (``amb.force_limit`` of the rig); every limit must be
        ``<= capacity``.

    """

    def __init__(self, basis: BasisSet, limit, capacity: float) -> None:
        limit = np.broadcast_to(np.asarray(limit, dtype=float), (basis.n_channels,)).copy()
        if not (np.isfinite(capacity) and capacity > 0):
            raise ControllerValueError(f"capacity must be a positive force in N, got {capacity}")
        if np.any(~np.isfinite(limit)) or np.any(limit <= 0) or np.any(limit > capacity):
            raise ControllerValueError(
                f"wavelet force limits must lie in (0, {capacity}] N (the bearing capacity), "
                f"got {limit.tolist()}; lower them or check amb.force_limit in rig.yaml"
            )
        self.basis = basis
        self.limit = limit
        energy = np.sum(basis.weights**2, axis=2)  # (n_coef, n_axes)
        self.axis_of = np.argmax(energy, axis=1)
        if np.any(np.sum(energy > 0, axis=1) > 1):
            raise ControllerValueError("each control coefficient must act on a single axis")

    def apply(self, coefficients: np.ndarray) -> SaturationResult:
        """
        Synthesise and limit one command.

        Parameters
        ----------
        coefficients : numpy.ndarray
            Control coefficients, shape ``(n_coefficients,)``.

        Returns
        -------
        SaturationResult

        """
        force = synthesize(coefficients, self.basis)
        peak = np.max(np.abs(force), axis=1)
        saturated = peak > self.limit
        scale = np.where(saturated, self.limit / np.where(peak > 0, peak, 1.0), 1.0)
        coefficients = np.asarray(coefficients, dtype=float) * scale[self.axis_of]
        force = force * scale[:, None]
        return SaturationResult(coefficients, force, saturated, peak * scale)
