"""
The 1 x Fourier bases of the baselines and the complex <-> real (cos, sin) layout.

The baselines (:mod:`amb_controller.baselines`) measure and force in these bases instead of the
Haar wavelets: :func:`fourier_measurement_basis` projects the measured sensors on the 1 x
harmonic of a period, :func:`fourier_control_basis` gives the 1 x force waveforms per axis;
:func:`complex_from_real`, :func:`real_from_complex`, :func:`complex_gain` and
:func:`real_gain` convert between the real coefficient layout and complex phasors.

Fourier basis (sampled harmonics)
---------------------------------
Over control period k (samples ``n = 0 .. N-1`` of the period, ``theta_n = 2 pi n / N``)::

    q_cos = sqrt(2/N) sum_n x[n] cos(theta_n),   q_sin = sqrt(2/N) sum_n x[n] sin(theta_n)
    f[n]  = sqrt(2/N) (u_cos cos(theta_n) + u_sin sin(theta_n))

The weights are orthonormal over the period, so the coefficient units are those of the
Haar coefficients (m sqrt(samples), N sqrt(samples)); a sinusoid of amplitude ``F`` N has
``|u| = F sqrt(N/2)``. The Haar square wave of the same peak force carries ``4/pi`` (1.27)
times more 1 x force: at equal peak limits the wavelet controller has this advantage, which
the comparison report states.

Complex form: ``Y = q_cos - i q_sin`` so that ``x[n] = sqrt(2/N) Re(Y e^{i theta_n})``; for a
linear time-invariant plant the steady-state map ``Y = T U`` is complex, and the real
``(cos, sin)`` block matrix is ``[[Tr, Ti], [-Ti, Tr]]`` (``T = Tr + i Ti``).
"""

from __future__ import annotations

import math

import numpy as np

from amb_common.names import N_AXES, N_SENSORS
from amb_controller.basis import BasisSet

__all__ = [
    "complex_from_real",
    "complex_gain",
    "fourier_control_basis",
    "fourier_measurement_basis",
    "real_from_complex",
    "real_gain",
    "sinusoid_control_basis",
]


def _harmonic(samples_per_rev: int) -> tuple[np.ndarray, np.ndarray]:
    theta = 2 * np.pi * np.arange(samples_per_rev) / samples_per_rev
    scale = math.sqrt(2.0 / samples_per_rev)
    return scale * np.cos(theta), scale * np.sin(theta)


def fourier_control_basis(samples_per_rev: int, n_axes: int = N_AXES) -> BasisSet:
    """
    Return the 1 x force waveforms ``sqrt(2/N) cos``, ``sqrt(2/N) sin`` per axis.

    Parameters
    ----------
    samples_per_rev : int
        Samples per period N.
    n_axes : int
        Bearing axes.

    Returns
    -------
    BasisSet
        ``2 n_axes`` coefficients, cos block then sin block (labels ``h1/cos/c{axis}``),
        ``offset = 0``; N per N sqrt(samples).

    """
    cos, sin = _harmonic(samples_per_rev)
    weights = np.zeros((2 * n_axes, n_axes, samples_per_rev))
    labels = []
    for b, (name, wave) in enumerate((("cos", cos), ("sin", sin))):
        for axis in range(n_axes):
            weights[b * n_axes + axis, axis] = wave
            labels.append(f"h1/{name}/c{axis}")
    return BasisSet(weights, 0, tuple(labels))


def sinusoid_control_basis(
    samples_per_rev: int, n_axes: int = N_AXES, quadratures=("even", "odd")
) -> BasisSet:
    """
    Return the 1 x force waveforms in the wavelet controller's coefficient layout.

    The waveforms of :func:`fourier_control_basis` (``sqrt(2/N) cos`` and ``sqrt(2/N) sin``
    per axis), labelled as the thesis level p = 1 of :func:`amb_controller.basis.control_basis`:
    ``p1/q1/even/c{axis}`` for the cosine and ``p1/q1/odd/c{axis}`` for the sine (the sine is
    the cosine a quarter period later, as the odd quadrature is the even one, section 4.3).
    With it the transient controller measures wavelet coefficients and forces with a sinusoid:
    the same control law (eq. 8.10) without the odd harmonics of the Haar square wave.

    Parameters
    ----------
    samples_per_rev : int
        Samples per period N.
    n_axes : int
        Bearing axes.
    quadratures : sequence of {"even", "odd"}
        Which of the cosine (even) and sine (odd) to use, in this order.

    Returns
    -------
    BasisSet
        ``len(quadratures) n_axes`` coefficients, quadrature-major then axis; N per
        N sqrt(samples), ``offset = 0``.

    """
    cos, sin = _harmonic(samples_per_rev)
    waves = {"even": cos, "odd": sin}
    rows, labels = [], []
    for quad in quadratures:
        for axis in range(n_axes):
            w = np.zeros((n_axes, samples_per_rev))
            w[axis] = waves[quad]
            rows.append(w)
            labels.append(f"p1/q1/{quad}/c{axis}")
    return BasisSet(np.array(rows), 0, tuple(labels))


def fourier_measurement_basis(samples_per_rev: int, sensors) -> BasisSet:
    """
    Return the 1 x analysis weights of the measured sensors (same layout as the control).

    Parameters
    ----------
    samples_per_rev : int
        Samples per period N.
    sensors : sequence of int
        Sensor channels 0..7 ([x1, y1, ..., x4, y4]) measured.

    Returns
    -------
    BasisSet
        ``2 len(sensors)`` coefficients over the 8 channels, cos block then sin block,
        ``offset = 0`` (the window is the period itself).

    """
    cos, sin = _harmonic(samples_per_rev)
    sensors = [int(s) for s in sensors]
    weights = np.zeros((2 * len(sensors), N_SENSORS, samples_per_rev))
    labels = []
    for b, (name, wave) in enumerate((("cos", cos), ("sin", sin))):
        for i, s in enumerate(sensors):
            weights[b * len(sensors) + i, s] = wave
            labels.append(f"h1/{name}/c{s}")
    return BasisSet(weights, 0, tuple(labels))


def complex_from_real(vector: np.ndarray) -> np.ndarray:
    """Return ``Y = q_cos - i q_sin`` from the real layout ``[q_cos..., q_sin...]``."""
    vector = np.asarray(vector, dtype=float)
    n = vector.shape[0] // 2
    return vector[:n] - 1j * vector[n:]


def real_from_complex(phasor: np.ndarray) -> np.ndarray:
    """Return the real layout ``[Re Y..., -Im Y...]`` of complex phasors (inverse of above)."""
    phasor = np.asarray(phasor, dtype=complex)
    return np.concatenate([phasor.real, -phasor.imag])


def complex_gain(real_gain: np.ndarray) -> np.ndarray:
    """
    Return the complex ``T`` of a real ``(cos, sin)`` block gain (module docstring).

    ``Tr = (M_cc + M_ss)/2``, ``Ti = (M_cs - M_sc)/2``: exact when the real gain has the
    complex structure (a linear time-invariant plant at one frequency), the closest
    complex map in the Frobenius norm otherwise.
    """
    m = np.asarray(real_gain, dtype=float)
    ny, nu = m.shape[0] // 2, m.shape[1] // 2
    cc, cs = m[:ny, :nu], m[:ny, nu:]
    sc, ss = m[ny:, :nu], m[ny:, nu:]
    return 0.5 * (cc + ss) + 0.5j * (cs - sc)


def real_gain(complex_t: np.ndarray) -> np.ndarray:
    """Return the real block gain ``[[Tr, Ti], [-Ti, Tr]]`` of a complex ``T``."""
    t = np.asarray(complex_t, dtype=complex)
    return np.block([[t.real, t.imag], [-t.imag, t.real]])
