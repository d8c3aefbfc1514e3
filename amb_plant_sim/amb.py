"""
AMB force laws per control axis (section 2.3).

``x`` is the rotor displacement along the axis (m), positive towards coil 1 (``x = -l_g`` of
eq. 2.32-2.37), ``i`` the control current (A, ``i_1 = -i_2 = i``).

- Linearised (eq. 2.37-2.40): ``f = K_i i + K_z x``.
- Opposing pair (eq. 2.33) with the levitation current ``I_s = 0`` (gravity is not in the
  lateral model): ``f = k [((I_b + i)/(c_g - x))^2 - ((I_b - i)/(c_g + x))^2]``, with ``k``
  and ``I_b`` from :attr:`AmbData.pair_constant` and :attr:`AmbData.bias_current`: its slopes
  at the origin are the rig's ``K_i`` and ``K_z`` (with rig.yaml's 2.24e6 N/m, ``k`` is Table
  2.2's ``mu0 N^2 A``; the measured mean 2.075e6 N/m would set it 8 % higher).
- Channel loss: ``both`` coils dead gives no force; a single working coil gives its own term;
  the current sensors then read what the coils carry (:func:`measured_current`).
- Saturation: the control part ``K_i i`` is limited to ``+-force_limit`` (1 kN, section 2.6),
  applied as a current limit ``force_limit / K_i``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from amb_common.rig import AmbData

NORMAL, LOST, COIL_POSITIVE, COIL_NEGATIVE = 0, 1, 2, 3
CHANNEL_MODES = {"both": LOST, "positive": COIL_POSITIVE, "negative": COIL_NEGATIVE}


def current_limit(amb: AmbData) -> float:
    """Largest control current magnitude (A) allowed by the force limit."""
    return amb.force_limit / amb.Ki


def linear_force(amb: AmbData, current: NDArray, x: NDArray) -> NDArray[np.float64]:
    """Linearised AMB force (eq. 2.37-2.40), N: ``K_i i + K_z x``."""
    return amb.Ki * np.asarray(current, float) + amb.Kz * np.asarray(x, float)


def coil_forces(amb: AmbData, current: NDArray, x: NDArray) -> tuple[NDArray, NDArray]:
    """
    Forces of the two coils of each opposing pair (eq. 2.33), N, signed along the axis.

    Returns
    -------
    f1 : ndarray
        Coil 1 (attracts towards +x): ``k ((I_b + i)/(c_g - x))^2``.
    f2 : ndarray
        Coil 2 (attracts towards -x): ``-k ((I_b - i)/(c_g + x))^2``.
    """
    k = amb.pair_constant
    ib, cg = amb.bias_current, amb.nominal_air_gap
    i = np.asarray(current, float)
    xx = np.clip(np.asarray(x, float), -0.95 * cg, 0.95 * cg)  # the laminations are not reached
    f1 = k * (np.maximum(ib + i, 0.0) / (cg - xx)) ** 2
    f2 = -k * (np.maximum(ib - i, 0.0) / (cg + xx)) ** 2
    return f1, f2


def pair_force(amb: AmbData, current: NDArray, x: NDArray) -> NDArray[np.float64]:
    """Nonlinear opposing-pair force (eq. 2.33), N."""
    f1, f2 = coil_forces(amb, current, x)
    return f1 + f2


def measured_current(amb: AmbData, current: NDArray, modes: NDArray) -> NDArray[np.float64]:
    """
    Control current per axis as the amplifiers' current sensors give it, A.

    The two coils of an axis carry ``I_b + i`` and ``I_b - i`` (eq. 2.33); the control
    current is half their difference, ``i`` while both work. A lost coil carries nothing:
    ``both`` lost reads 0, coil 1 alone ``(I_b + i) / 2``, coil 2 alone ``(i - I_b) / 2`` (a
    step of ``I_b / 2`` = 2.35 A with the rig's slopes and the gain halved). What the demand ``i``
    asked for and what the coils carry then differ: the fault monitor's coil check
    (:mod:`amb_fault_monitor.coil_check`).

    Parameters
    ----------
    amb : AmbData
    current : ndarray (..., 4)
        Control current demanded per axis (after the limit), A.
    modes : ndarray (..., 4) of int
        ``NORMAL``, ``LOST``, ``COIL_POSITIVE``, ``COIL_NEGATIVE`` per axis.

    Returns
    -------
    ndarray (..., 4)
    """
    i = np.asarray(current, float)
    modes = np.asarray(modes)
    if not np.any(modes != NORMAL):
        return i
    ib = amb.bias_current
    coil1 = np.where((modes == NORMAL) | (modes == COIL_POSITIVE), ib + i, 0.0)
    coil2 = np.where((modes == NORMAL) | (modes == COIL_NEGATIVE), ib - i, 0.0)
    return 0.5 * (coil1 - coil2)


def amb_force(
    amb: AmbData, current: NDArray, x: NDArray, modes: NDArray, law: str | None = None
) -> NDArray[np.float64]:
    """
    AMB force per axis with channel faults, N.

    Parameters
    ----------
    amb : AmbData
    current : ndarray (4,)
        Control current per axis, A (already limited).
    x : ndarray (4,)
        Rotor displacement at the bearing per axis, m.
    modes : ndarray (4,) of int
        ``NORMAL``, ``LOST``, ``COIL_POSITIVE``, ``COIL_NEGATIVE`` per axis.
    law : str, optional
        ``linear`` or ``nonlinear`` (default ``amb.law``).

    Returns
    -------
    ndarray (4,)
    """
    law = amb.law if law is None else law
    f = linear_force(amb, current, x) if law == "linear" else pair_force(amb, current, x)
    modes = np.asarray(modes)
    if np.any(modes != NORMAL):
        f1, f2 = coil_forces(amb, current, x)
        f = np.where(modes == LOST, 0.0, f)
        f = np.where(modes == COIL_POSITIVE, f1, f)
        f = np.where(modes == COIL_NEGATIVE, f2, f)
    return f
