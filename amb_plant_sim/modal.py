"""
Modal analysis of the first-order model (eq. 2.17-2.21): frequencies, damping, whirl, shapes.

Frequencies are the damped natural frequencies ``Im(lambda) / 2 pi`` (Hz) of the eigenvalues
``lambda`` with positive imaginary part; the damping ratio is ``-Re(lambda)/|lambda|``.
Whirl direction from the eigenvector: with ``x = Re(v_x e^{lambda t})`` a forward whirl (in the
direction of spin, x towards y) has ``v_y = -j v_x``, so ``|v_x + j v_y|`` measures the forward
and ``|v_x - j v_y|`` the backward component, summed over the nodes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from amb_common.rig import Rig
from amb_plant_sim.closed_loop import build_closed_loop, build_plant
from amb_plant_sim.rotor import RotorModel, build_rotor

#: Eigenvalues this close (relative) are one double eigenvalue. At zero speed the rig's x/y
#: copies differ by rounding alone (1e-12 to 1e-10 of |lambda|); gyroscopic coupling splits
#: them by 6e-6 of |lambda| already at 0.01 Hz running speed.
DEGENERATE_REL = 1e-8


@dataclass(frozen=True)
class Mode:
    """
    One vibration mode.

    Attributes
    ----------
    eigenvalue : complex
        lambda, 1/s.
    frequency_hz : float
        Damped natural frequency Im(lambda)/2 pi, Hz.
    damping_ratio : float
        -Re(lambda)/|lambda|.
    whirl : str
        ``forward``, ``backward`` or ``planar`` (no preferred direction: zero speed).
    shape : ndarray (N, 2) complex
        Nodal ``[x, y]`` of the eigenvector, normalised to unit largest magnitude.
    """

    eigenvalue: complex
    frequency_hz: float
    damping_ratio: float
    whirl: str
    shape: NDArray[np.complex128]

    def as_dict(self) -> dict[str, float | str]:
        """JSON-ready summary: frequency (Hz), damping ratio, whirl."""
        return {
            "frequency_hz": round(self.frequency_hz, 6),
            "damping_ratio": round(self.damping_ratio, 6),
            "whirl": self.whirl,
        }


def modes_from_matrix(
    A: NDArray[np.float64],
    n_dof: int,
    min_frequency_hz: float = 0.05,
    max_frequency_hz: float = math.inf,
    max_damping_ratio: float = 0.95,
) -> list[Mode]:
    """
    Modes of a first-order system whose state starts with the ``n_dof`` nodal displacements.

    Parameters
    ----------
    A : ndarray (n, n)
        State matrix (eq. 2.16 or 2.47).
    n_dof : int
        Number of rotor DOFs (4N); the first ``n_dof`` states are the nodal displacements.
    min_frequency_hz, max_frequency_hz : float
        Keep modes with damped frequency in this range (drops real and rigid-body poles).
    max_damping_ratio : float
        Drop nearly real poles (the PID integrator and derivative-filter poles, which the
        gyroscopic coupling makes slightly complex at speed): they are not vibration modes.

    Returns
    -------
    list of Mode
        Sorted by frequency.
    """
    lam, V = scipy.linalg.eig(A)
    zeta = -lam.real / np.maximum(np.abs(lam), 1e-300)
    keep = (
        (lam.imag / (2 * math.pi) > min_frequency_hz)
        & (lam.imag / (2 * math.pi) < max_frequency_hz)
        & (zeta < max_damping_ratio)
    )
    out = []
    kept = lam[keep]
    for k in np.flatnonzero(keep):
        v = V[:n_dof, k]
        xy = np.stack([v[0::4], v[1::4]], axis=1)
        fwd = float(np.sum(np.abs(xy[:, 0] + 1j * xy[:, 1]) ** 2))
        bwd = float(np.sum(np.abs(xy[:, 0] - 1j * xy[:, 1]) ** 2))
        tot = fwd + bwd
        # A double eigenvalue (the x/y copies of an axisymmetric rotor at zero speed) has a
        # two-dimensional eigenspace: any mix of its forward and backward circles is an
        # eigenvector, and rounding picks the mix. It has no whirl direction.
        degenerate = np.count_nonzero(np.abs(kept - lam[k]) <= DEGENERATE_REL * abs(lam[k])) > 1
        if tot == 0.0 or degenerate:
            whirl = "planar"
        elif fwd > 0.99 * tot:
            whirl = "forward"
        elif bwd > 0.99 * tot:
            whirl = "backward"
        else:
            whirl = "planar"
        big = np.max(np.abs(xy))
        shape = xy / (xy.flat[np.argmax(np.abs(xy))] if big > 0 else 1.0)
        lk = complex(lam[k])
        out.append(
            Mode(
                eigenvalue=lk,
                frequency_hz=lk.imag / (2 * math.pi),
                damping_ratio=-lk.real / abs(lk),
                whirl=whirl,
                shape=shape,
            )
        )
    out.sort(key=lambda m: m.frequency_hz)
    return out


def distinct_modes(modes: list[Mode], rel_tol: float = 1e-5) -> list[Mode]:
    """
    Merge repeated eigenvalues (the x and y copies of each mode at zero speed).

    Parameters
    ----------
    modes : list of Mode
        Sorted by frequency.
    rel_tol : float
        Relative eigenvalue distance under which two modes are one.

    Returns
    -------
    list of Mode
    """
    out: list[Mode] = []
    for m in modes:
        if out and abs(m.eigenvalue - out[-1].eigenvalue) <= rel_tol * abs(m.eigenvalue):
            continue
        out.append(m)
    return out


def free_free_modes(rig: Rig, omega: float = 0.0, rotor: RotorModel | None = None) -> list[Mode]:
    """Modes of the free-free rotor (no AMB, no PID) at speed ``omega`` (rad/s), figure 2.4/2.7."""
    plant = build_plant(rig, omega, rotor=rotor, amb_stiffness=False, amplifier="ideal")
    return modes_from_matrix(plant.A, plant.rotor.n_dof, min_frequency_hz=0.5)


def closed_loop_modes(
    rig: Rig,
    omega: float = 0.0,
    rotor: RotorModel | None = None,
    gains=None,
    amplifier: str | None = None,
) -> list[Mode]:
    """Modes of the rotor with AMBs and the PID (eq. 2.47) at speed ``omega`` (rad/s)."""
    cl = build_closed_loop(rig, omega, rotor=rotor, gains=gains, amplifier=amplifier)
    return modes_from_matrix(cl.A, cl.plant.rotor.n_dof)


def natural_frequencies(rig: Rig, count: int = 4, rotor: RotorModel | None = None) -> list[float]:
    """
    First ``count`` distinct zero-speed natural frequencies (Hz) of the PID closed loop.

    These are the numbers the calibration matches to the thesis's 11, 18, 29 and 67 Hz.
    """
    modes = distinct_modes(closed_loop_modes(rig, 0.0, rotor=rotor))
    return [m.frequency_hz for m in modes[:count]]


def is_stable(A: NDArray[np.float64], margin: float = 0.0) -> bool:
    """True if every eigenvalue of ``A`` has real part below ``-margin`` (1/s)."""
    return bool(np.max(np.linalg.eigvals(A).real) < -margin)


def critical_speeds(
    rig: Rig,
    count: int = 4,
    rotor: RotorModel | None = None,
    tol_hz: float = 1e-4,
    max_iter: int = 50,
    start_hz: Sequence[float] | None = None,
) -> list[float]:
    """
    Return the critical speeds (Hz) of the PID closed loop.

    Running speeds equal to a forward-whirl natural frequency, ``f_k(Omega) = Omega / 2 pi``
    (crossings of the synchronous line of the Campbell diagram, figure 2.7).

    Solved by fixed-point iteration from the zero-speed frequencies, following the k-th
    forward mode (or the k-th mode when whirl is mixed).

    Parameters
    ----------
    rig : Rig
    count : int
        Number of critical speeds.
    rotor : RotorModel, optional
    tol_hz : float
        Convergence tolerance, Hz.
    max_iter : int
        Iteration limit.
    start_hz : sequence of float, optional
        The first ``count`` zero-speed frequencies (:func:`natural_frequencies`), Hz, where the
        caller has them already (a fit's trial): the iterations start there. None: computed.

    Returns
    -------
    list of float
        Critical speeds, Hz, increasing.
    """
    rot = build_rotor(rig) if rotor is None else rotor
    f0 = natural_frequencies(rig, count, rotor=rot) if start_hz is None else start_hz[:count]
    out = []
    for f_start in f0:
        f = f_start
        for _ in range(max_iter):
            modes = closed_loop_modes(rig, 2 * math.pi * f, rotor=rot)
            fw = [m for m in modes if m.whirl == "forward"] or modes
            f_new = min(fw, key=lambda m: abs(m.frequency_hz - f)).frequency_hz
            if abs(f_new - f) < tol_hz:
                f = f_new
                break
            f = f_new
        out.append(f)
    return out
