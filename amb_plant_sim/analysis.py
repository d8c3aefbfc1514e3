"""
Analyses of chapter 2 as arrays.

Campbell data (figure 2.7), convergence with the number of elements (figure 2.6), frequencies
against proportional gain (figure 2.13), singular values from AMB forces to sensors (figures
2.16-2.17), mode shapes (figures 2.4, 2.15), and the sensitivity function at each bearing axis
with its ISO 14839-3 zone.

Sensitivity (ISO 14839-3): with all other loops closed, a signal injected at the controller
output of one axis and the total signal after the summing point give ``G_s = 1 / (1 + G_o)``
(``G_o`` the open loop of that axis). In the closed loop of eq. (2.47) this is
``G_s(jw) = 1 + H(jw)``, ``H`` the transfer from the injected current to the PID's current of
the same axis. Zones by the peak of ``|G_s|``: A < 3 (9.5 dB), B < 4 (12 dB), C < 5 (14 dB),
D otherwise (ISO 14839-3:2006, Table 1: limits of the peak sensitivity for the evaluation of
stability margins).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from amb_common.names import AXIS_NAMES
from amb_common.rig import Rig
from amb_plant_sim.closed_loop import ClosedLoop, build_closed_loop
from amb_plant_sim.modal import (
    Mode,
    closed_loop_modes,
    distinct_modes,
    free_free_modes,
)
from amb_plant_sim.rotor import build_rotor

ISO_ZONE_LIMITS = ((3.0, "A"), (4.0, "B"), (5.0, "C"))
#: An eigenvalue with |Im| below this fraction of |lambda| is real (see frequencies_vs_gain).
REAL_REL = 1e-5


def campbell(
    rig: Rig,
    speeds_hz: NDArray[np.float64],
    free_free: bool = False,
    max_frequency_hz: float = 300.0,
    elements: int | None = None,
) -> list[list[Mode]]:
    """
    Modes at each running speed (Campbell diagram, figure 2.7).

    Parameters
    ----------
    rig : Rig
    speeds_hz : array of float
        Running speeds, Hz.
    free_free : bool
        Free-free rotor (figure 2.7) instead of the PID closed loop.
    max_frequency_hz : float
        Highest frequency kept, Hz.
    elements : int, optional
        Element count.

    Returns
    -------
    list of list of Mode
        Per speed, the modes sorted by frequency (zero speed: x/y copies merged).
    """
    rot = build_rotor(rig, elements)
    out = []
    for f in np.asarray(speeds_hz, float):
        omega = 2 * math.pi * f
        modes = (
            free_free_modes(rig, omega, rot) if free_free else closed_loop_modes(rig, omega, rot)
        )
        modes = [m for m in modes if m.frequency_hz <= max_frequency_hz]
        out.append(distinct_modes(modes) if f == 0.0 else modes)
    return out


def frequencies_vs_elements(
    rig: Rig, element_counts: list[int], count: int = 4
) -> NDArray[np.float64]:
    """
    Return the first free-free natural frequencies per element count (figure 2.6).

    The first ``count`` non-zero ones (Hz) at zero speed; shape
    ``(len(element_counts), count)``.
    """
    out = np.zeros((len(element_counts), count))
    for k, ne in enumerate(element_counts):
        modes = distinct_modes(free_free_modes(rig, 0.0, build_rotor(rig, ne)))
        out[k] = [m.frequency_hz for m in modes[:count]]
    return out


def frequencies_vs_gain(
    rig: Rig, kp_values: NDArray[np.float64], count: int = 5
) -> NDArray[np.float64]:
    """
    Return the zero-speed natural frequencies against the proportional gain (figure 2.13).

    The first ``count`` (Hz), with integral and derivative gains zero.

    Unstable real eigenvalue pairs (negative stiffness not overcome) count as modes at 0 Hz,
    as in the thesis's figure. Shape ``(len(kp_values), count)``.
    """
    rot = build_rotor(rig)
    out = np.zeros((len(kp_values), count))
    for k, kp in enumerate(np.asarray(kp_values, float)):
        g = replace(rig.pid, Kp=float(kp), KI=0.0, Kd=0.0)
        cl = build_closed_loop(rig, 0.0, rotor=rot, gains=g)
        lam = np.linalg.eigvals(cl.A)
        # Each unstable real eigenvalue is double (x and y planes): rounding splits the pair
        # into two real values or a complex pair with |Im| ~ 1e-8 |lambda|; a vibration mode
        # has Im of the order of |lambda|. The cut is relative for that reason.
        real = np.abs(lam.imag) < REAL_REL * np.abs(lam)
        n_real_unstable = int(np.sum((lam.real > 1e-6) & real))
        freqs = np.sort(lam.imag[(lam.imag > 0) & ~real]) / (2 * math.pi)
        dedup: list[float] = []
        for f in freqs:
            if not dedup or abs(f - dedup[-1]) > 1e-6 * max(f, 1.0):
                dedup.append(float(f))
        vals = [0.0] * (n_real_unstable // 2) + dedup  # x and y planes: pairs
        out[k] = (vals + [math.nan] * count)[:count]
    return out


def _transfer(
    cl: ClosedLoop, C: NDArray, B: NDArray, freqs_hz: NDArray[np.float64]
) -> NDArray[np.complex128]:
    """``C (jw I - A)^-1 B`` at each frequency (eq. 2.53), shape (nf, ny, nu)."""
    lam, V = np.linalg.eig(cl.A)
    Vi_B = np.linalg.solve(V, B)
    CV = C @ V
    w = 2j * math.pi * np.asarray(freqs_hz, float)
    return np.einsum("yk,fk,ku->fyu", CV, 1.0 / (w[:, None] - lam[None, :]), Vi_B)


def singular_values(
    rig: Rig, freqs_hz: NDArray[np.float64], speed_hz: float = 0.0
) -> NDArray[np.float64]:
    """
    Return the singular values of the PID closed loop's frequency response (figure 2.16).

    From the four AMB control forces (N) to the eight sensors (m), eq. 2.54. Shape
    ``(nf, 4)``, m/N.
    """
    cl = build_closed_loop(rig, 2 * math.pi * speed_hz)
    G = _transfer(cl, cl.output(cl.plant.C_s), cl.B_u, freqs_hz)
    return np.linalg.svd(G, compute_uv=False)


def sensitivity(
    rig: Rig, freqs_hz: NDArray[np.float64], speed_hz: float = 0.0
) -> NDArray[np.complex128]:
    """
    Sensitivity ``G_s(jw)`` at each bearing axis with the other loops closed (ISO 14839-3).

    Returns
    -------
    ndarray (nf, 4) complex
        Columns in axis order [b1x, b1y, b2x, b2y].
    """
    cl = build_closed_loop(rig, 2 * math.pi * speed_hz)
    H_rows = np.hstack([cl.pid.D @ cl.plant.C_in, cl.pid.C])  # PID current per axis
    H = _transfer(cl, H_rows, cl.B_i, freqs_hz)
    return 1.0 + np.einsum("faa->fa", H)


@dataclass(frozen=True)
class SensitivityPeak:
    """Peak of ``|G_s|`` at one axis: value, dB, frequency (Hz) and ISO 14839-3 zone."""

    axis: str
    peak: float
    peak_db: float
    frequency_hz: float
    zone: str

    def as_dict(self) -> dict[str, float | str]:
        """JSON-ready."""
        return {
            "axis": self.axis,
            "peak": round(self.peak, 4),
            "peak_db": round(self.peak_db, 3),
            "frequency_hz": round(self.frequency_hz, 3),
            "zone": self.zone,
        }


def iso_zone(peak: float) -> str:
    """ISO 14839-3 zone (A/B/C/D) of a sensitivity peak (absolute value)."""
    for limit, zone in ISO_ZONE_LIMITS:
        if peak < limit:
            return zone
    return "D"


def sensitivity_peaks(
    rig: Rig, speed_hz: float = 0.0, f_min: float = 1.0, f_max: float = 2000.0, n: int = 4000
) -> list[SensitivityPeak]:
    """Peak sensitivity per axis over ``[f_min, f_max]`` Hz (log grid, refined at the peak)."""
    f = np.geomspace(f_min, f_max, n)
    S = np.abs(sensitivity(rig, f, speed_hz))
    out = []
    for a, name in enumerate(AXIS_NAMES):
        k = int(np.argmax(S[:, a]))
        lo, hi = f[max(k - 1, 0)], f[min(k + 1, n - 1)]
        fr = np.linspace(lo, hi, 201)
        Sr = np.abs(sensitivity(rig, fr, speed_hz)[:, a])
        j = int(np.argmax(Sr))
        pk = float(Sr[j])
        out.append(SensitivityPeak(name, pk, 20 * math.log10(pk), float(fr[j]), iso_zone(pk)))
    return out


def mode_shapes(modes: list[Mode], count: int = 4) -> NDArray[np.float64]:
    """
    Real planar shapes of the first ``count`` modes along the nodes (figures 2.4, 2.15).

    The x component of each complex shape is rotated to be real (largest entry +1).
    Shape ``(count, N)``.
    """
    out = []
    for m in modes[:count]:
        x = m.shape[:, 0] if np.abs(m.shape[:, 0]).max() > 0 else m.shape[:, 1]
        k = int(np.argmax(np.abs(x)))
        x = (x / x[k]).real
        out.append(x)
    return np.asarray(out)
