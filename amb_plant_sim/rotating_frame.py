"""
Synchronous rotating-frame form of the model, eq. (2.22)-(2.30).

With ``x = T(t) r`` and ``T`` the rotation by the rotor angle ``O t`` applied to every pair of
coordinates that rotates as a vector about the spin axis (``(x, y)`` and ``(alpha, beta)`` of
each node), ``T' = O Delta T`` and ``T'' = -O^2 T`` (eq. 2.27-2.28). For an axisymmetric
(isotropic) rotor and isotropic bearings the matrices commute with ``T`` and the equation of
motion in the rotating frame is

    M r'' + (D + 2 O M Delta) r' + (K + O D Delta - O^2 M) r = T^T f,   D = O G + C,

which is eq. (2.30) with the sign of the centrifugal term corrected: the thesis prints
``+ O^2 M``, but ``M T'' r = -O^2 M T r`` (eq. 2.27) gives ``- O^2 M`` (a Jeffcott rotor's
rotating-frame stiffness ``k - m O^2`` vanishes at its critical speed, as it must).

Sign decision. Eq. (2.26) prints ``T = [[cos Ot, sin Ot], [-sin Ot, cos Ot]]`` (a rotation by
``-O t``) with ``Delta = [[0, 1], [-1, 0]]``; with that ``T`` a forward synchronous force
(eq. 5.1, ``f_x + j f_y = m e O^2 e^{j O t}``, spin from x towards y) would NOT be constant in
the frame, contrary to eq. (5.2). Here ``T = [[cos Ot, -sin Ot], [sin Ot, cos Ot]]`` and
``Delta = [[0, -1], [1, 0]]`` (eq. 2.26/2.29 with ``O -> -O``), so that ``u + j v =
e^{-j O t} (x + j y)`` and the unbalance force is constant, as eq. (5.2) states.

This is the MODEL transform; the SIGNAL transform of measured ``(x, y, angle) -> (u, v)``
lives in ``amb_wavelet.frames``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from amb_common.errors import RigError


def delta_matrix(n_dof: int) -> NDArray[np.float64]:
    """
    ``Delta`` of eq. (2.29) on all rotating pairs: ``(x, y)`` and ``(alpha, beta)`` per node.

    Parameters
    ----------
    n_dof : int
        4N, DOFs ordered ``[x, y, alpha, beta]`` per node.

    Returns
    -------
    ndarray (n_dof, n_dof)
    """
    if n_dof % 4:
        raise RigError(f"n_dof must be a multiple of 4 (x, y, alpha, beta per node), got {n_dof}")
    d = np.array([[0.0, -1.0], [1.0, 0.0]])
    return np.kron(np.eye(n_dof // 2), d)


def rotation_matrix(n_dof: int, angle: float) -> NDArray[np.float64]:
    """``T`` (eq. 2.26, sign as in the module docstring) at ``angle = Omega t`` (rad)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.kron(np.eye(n_dof // 2), np.array([[c, -s], [s, c]]))


@dataclass(frozen=True)
class RotatingFrameModel:
    """Rotating-frame matrices ``M_r``, ``C_r``, ``K_r`` (eq. 2.30, corrected) at ``omega``."""

    omega: float
    M: NDArray[np.float64]
    C: NDArray[np.float64]
    K: NDArray[np.float64]


def to_rotating_frame(
    M: NDArray[np.float64],
    D: NDArray[np.float64],
    K: NDArray[np.float64],
    omega: float,
    check_isotropy: bool = True,
) -> RotatingFrameModel:
    """
    Synchronous rotating-frame form of ``M x'' + D x' + K x = f`` (eq. 2.25-2.30).

    Parameters
    ----------
    M, D, K : ndarray (n, n)
        Fixed-frame mass, damping (``Omega G + C``) and stiffness matrices, DOFs as eq. (2.1).
    omega : float
        Frame speed Omega, rad/s.
    check_isotropy : bool
        Verify that the matrices commute with ``Delta`` (an isotropic rotor/bearing system):
        only then are the rotating-frame matrices time-invariant.

    Returns
    -------
    RotatingFrameModel

    Raises
    ------
    RigError
        If ``check_isotropy`` and a matrix does not commute with ``Delta`` (anisotropic
        supports make the rotating-frame model periodic in time, not constant).
    """
    n = M.shape[0]
    Dl = delta_matrix(n)
    if check_isotropy:
        for name, X in (("M", M), ("D", D), ("K", K)):
            err = np.abs(X @ Dl - Dl @ X).max()
            if err > 1e-9 * max(np.abs(X).max(), 1e-300):
                raise RigError(
                    f"{name} does not commute with Delta (relative {err / np.abs(X).max():.2e}):"
                    " the system is not isotropic, so the rotating-frame model is time-varying;"
                    " pass check_isotropy=False only if you know why"
                )
    return RotatingFrameModel(
        omega=omega,
        M=M.copy(),
        C=D + 2.0 * omega * M @ Dl,
        K=K + omega * D @ Dl - omega**2 * M,
    )
