"""
Decentralised PID of the rig (section 2.6, eq. 2.45-2.46, Table 2.3).

Per bearing axis, the demand current from the inner sensor displacement ``y`` (m) is

    i_ref = -(1 / K_i) (K_p + K_I / s + K_d s / (1 + tau s)) y,   tau = 1 / derivative_cutoff,

so that the AMB's control force ``K_i i_ref`` is the Table 2.3 law in N/m. State per axis:
integrator ``x_I`` (m s) and derivative filter ``x_F`` with ``x_F' = -x_F / tau + y``; then
``K_d s/(1 + tau s) y = (K_d / tau)(y - x_F / tau)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from amb_common.rig import PidGains


@dataclass(frozen=True)
class StateSpace:
    """Matrices ``(A, B, C, D)`` of ``x' = A x + B u, y = C x + D u`` (or discrete ``x+``)."""

    A: NDArray[np.float64]
    B: NDArray[np.float64]
    C: NDArray[np.float64]
    D: NDArray[np.float64]


def pid_state_space(gains: PidGains, current_gain: float, n_axes: int = 4) -> StateSpace:
    """
    Continuous PID of eq. (2.45)-(2.46) for ``n_axes`` independent axes.

    Parameters
    ----------
    gains : PidGains
        Table 2.3 gains in force units (N/m, N/(m s), N s/m) and the cut-off (rad/s).
    current_gain : float
        AMB current gain K_i, N/A, to turn the demand force into a demand current.
    n_axes : int
        Number of control axes (4 for the rig: b1x, b1y, b2x, b2y).

    Returns
    -------
    StateSpace
        States ``[x_I, x_F]`` per axis (axis-major), input displacement (m), output current (A).
    """
    tau = 1.0 / gains.derivative_cutoff
    a1 = np.array([[0.0, 0.0], [0.0, -1.0 / tau]])
    b1 = np.array([[1.0], [1.0]])
    c1 = np.array([[-gains.KI, gains.Kd / tau**2]]) / current_gain
    d1 = np.array([[-(gains.Kp + gains.Kd / tau)]]) / current_gain
    eye = np.eye(n_axes)
    return StateSpace(np.kron(eye, a1), np.kron(eye, b1), np.kron(eye, c1), np.kron(eye, d1))


def discretize_zoh(ss: StateSpace, h: float) -> StateSpace:
    """
    Zero-order-hold discretisation at step ``h`` (s): exact for inputs held over each step.

    Returns ``(A_d, B_d, C, D)`` with ``A_d = e^{A h}``, ``B_d = integral_0^h e^{A s} ds B``.
    """
    n, m = ss.B.shape
    blk = np.zeros((n + m, n + m))
    blk[:n, :n] = ss.A
    blk[:n, n:] = ss.B
    E = scipy.linalg.expm(blk * h)
    return StateSpace(E[:n, :n], E[:n, n:], ss.C.copy(), ss.D.copy())


def pid_frequency_response(gains: PidGains, omega: NDArray[np.float64]) -> NDArray[np.complex128]:
    """
    PID force law ``K_p + K_I/(j w) + K_d j w/(1 + tau j w)`` in N/m at frequencies ``omega``.

    Parameters
    ----------
    gains : PidGains
        Table 2.3 gains.
    omega : ndarray
        Angular frequencies, rad/s (non-zero).

    Returns
    -------
    ndarray of complex
        The controller's force per displacement (figure 2.14 is its Bode plot).
    """
    s = 1j * np.asarray(omega, float)
    tau = 1.0 / gains.derivative_cutoff
    return gains.Kp + gains.KI / s + gains.Kd * s / (1.0 + tau * s)
