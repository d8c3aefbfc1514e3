"""
Finite element matrices of the rotor: Timoshenko shaft element and rigid disk.

Degrees of freedom per node follow eq. (2.1): ``[x, y, alpha, beta]``. ``alpha`` is the small
rotation about the x axis and ``beta`` the small rotation about the y axis, so that for the
shaft centre line ``beta = dx/dz`` and ``alpha = -dy/dz``. With the spin ``Omega`` about +z
(x turning towards y) this gives the disk gyroscopic matrix of eq. (2.13) with ``+I_p`` at
(alpha, beta) and the disk mass matrix of eq. (2.12) for an offset ``l_d``.

The shaft element is the rotating Timoshenko beam of Nelson (1980), the shear-deformable form
of Nelson & McVaugh (1976) used in eq. (2.4)-(2.9): cubic interpolation with the shear
parameter ``Phi = 12 E I / (kappa G A L^2)``, consistent translational and rotary mass,
gyroscopic matrix ``G = 2 x`` rotary mass (``I_p = 2 I``) in x-y coupled form. Internal damping
after Zorzi & Nelson (1977), eq. (2.10)-(2.11), uses the circulatory matrix ``K_c`` (the bending
stiffness with the x and y planes cross-coupled, skew-symmetric). Axial load (``K_a`` of
eq. 2.8-2.9) is not modelled: the rig carries none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

# Index of the planar (w1, theta1, w2, theta2) coordinates in the 8 element DOFs.
X_PLANE = np.array([0, 3, 4, 7])  # (x1, beta1, x2, beta2): theta = beta = dx/dz
Y_PLANE = np.array([1, 2, 5, 6])  # (y1, alpha1, y2, alpha2): theta = -alpha = dy/dz
_T = np.diag([1.0, -1.0, 1.0, -1.0])  # maps (y, alpha) coordinates to (w, theta) of the y plane


def shear_coefficient(poisson: float, inner_radius: float, outer_radius: float) -> float:
    """
    Timoshenko shear coefficient of a circular (hollow) section after Cowper (1966).

    Parameters
    ----------
    poisson : float
        Poisson's ratio.
    inner_radius, outer_radius : float
        Radii, m (``inner_radius = 0`` for a solid shaft).

    Returns
    -------
    float
        ``kappa = 6 (1 + nu)(1 + m^2)^2 / ((7 + 6 nu)(1 + m^2)^2 + (20 + 12 nu) m^2)``,
        ``m = r_i / r_o``; 0.886 for a solid steel shaft.
    """
    m2 = (inner_radius / outer_radius) ** 2
    nu = poisson
    return 6 * (1 + nu) * (1 + m2) ** 2 / ((7 + 6 * nu) * (1 + m2) ** 2 + (20 + 12 * nu) * m2)


def timoshenko_planar(
    length: float,
    E: float,
    I: float,  # noqa: E741 - the thesis's symbol
    rho: float,
    area: float,
    phi: float,
    rotary_inertia: bool = True,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """
    Planar Timoshenko beam matrices for coordinates ``(w1, theta1, w2, theta2)``.

    Parameters
    ----------
    length : float
        Element length L, m.
    E : float
        Young's modulus, Pa.
    I : float
        Second moment of area, m^4.
    rho : float
        Density, kg/m^3.
    area : float
        Cross-section area, m^2.
    phi : float
        Shear parameter ``12 E I / (kappa G A L^2)`` (0 for Euler-Bernoulli).
    rotary_inertia : bool
        Include the rotary inertia (eq. 2.5).

    Returns
    -------
    m_t : ndarray (4, 4)
        Translational mass, kg (eq. 2.4).
    r_unit : ndarray (4, 4)
        Rotary mass per unit rotary inertia ``integral N_r^T N_r ds``, 1/m; the rotary mass is
        ``rho I r_unit`` and the gyroscopic coupling uses ``rho I_p r_unit``.
    k_b : ndarray (4, 4)
        Bending stiffness, N/m (eq. 2.7).
    """
    L = length
    p = phi
    c = rho * area * L / (840.0 * (1 + p) ** 2)
    m1 = 312 + 588 * p + 280 * p**2
    m2 = (44 + 77 * p + 35 * p**2) * L
    m3 = 108 + 252 * p + 140 * p**2
    m4 = -(26 + 63 * p + 35 * p**2) * L
    m5 = (8 + 14 * p + 7 * p**2) * L**2
    m6 = -(6 + 14 * p + 7 * p**2) * L**2
    m_t = c * np.array([[m1, m2, m3, m4], [m2, m5, -m4, m6], [m3, -m4, m1, -m2], [m4, m6, -m2, m5]])
    if rotary_inertia:
        cr = 1.0 / (30.0 * L * (1 + p) ** 2)
        r1 = 36.0
        r2 = (3 - 15 * p) * L
        r3 = (4 + 5 * p + 10 * p**2) * L**2
        r4 = (-1 - 5 * p + 5 * p**2) * L**2
        r_unit = cr * np.array(
            [[r1, r2, -r1, r2], [r2, r3, -r2, r4], [-r1, -r2, r1, -r2], [r2, r4, -r2, r3]]
        )
    else:
        r_unit = np.zeros((4, 4))
    ck = E * I / (L**3 * (1 + p))
    k_b = ck * np.array(
        [
            [12, 6 * L, -12, 6 * L],
            [6 * L, (4 + p) * L**2, -6 * L, (2 - p) * L**2],
            [-12, -6 * L, 12, -6 * L],
            [6 * L, (2 - p) * L**2, -6 * L, (4 + p) * L**2],
        ]
    )
    return m_t, r_unit, k_b


@dataclass(frozen=True)
class ShaftElement:
    """8x8 matrices of one rotating shaft element in DOFs ``[x1 y1 a1 b1 x2 y2 a2 b2]``."""

    M: NDArray[np.float64]  # mass, kg (translational + rotary)
    G: NDArray[np.float64]  # gyroscopic (multiplied by Omega), kg m^2
    K: NDArray[np.float64]  # bending stiffness K_b, N/m
    Kc: NDArray[np.float64]  # circulatory matrix K_c of eq. (2.10), N/m (skew-symmetric)


def shaft_element(
    length: float,
    E: float,
    G_shear: float,
    rho: float,
    inner_radius: float,
    outer_radius: float,
    poisson: float,
    shear: bool = True,
    rotary_inertia: bool = True,
) -> ShaftElement:
    """
    Rotating Timoshenko shaft element (eq. 2.4-2.10) in the 4-DOF-per-node coordinates.

    Parameters
    ----------
    length : float
        Element length, m.
    E, G_shear : float
        Young's and shear moduli, Pa.
    rho : float
        Density, kg/m^3.
    inner_radius, outer_radius : float
        Radii, m.
    poisson : float
        Poisson's ratio (for the shear coefficient).
    shear : bool
        Include shear deformation (Timoshenko); ``False`` gives the Rayleigh/Euler-Bernoulli beam.
    rotary_inertia : bool
        Include rotary inertia and the gyroscopic matrix.

    Returns
    -------
    ShaftElement
    """
    area = math.pi * (outer_radius**2 - inner_radius**2)
    I = math.pi * (outer_radius**4 - inner_radius**4) / 4.0  # noqa: E741
    if shear:
        kappa = shear_coefficient(poisson, inner_radius, outer_radius)
        phi = 12.0 * E * I / (kappa * G_shear * area * length**2)
    else:
        phi = 0.0
    m_t, r_unit, k_b = timoshenko_planar(length, E, I, rho, area, phi, rotary_inertia)
    m_p = m_t + rho * I * r_unit
    M = np.zeros((8, 8))
    K = np.zeros((8, 8))
    Gm = np.zeros((8, 8))
    Kc = np.zeros((8, 8))
    ix, iy = np.ix_(X_PLANE, X_PLANE), np.ix_(Y_PLANE, Y_PLANE)
    M[ix] = m_p
    M[iy] = _T @ m_p @ _T
    K[ix] = k_b
    K[iy] = _T @ k_b @ _T
    # Gyroscopic: G = P - P^T with P[y, x] = -rho Ip T R (I_p = 2 I), see module docstring.
    ip_r = 2.0 * rho * I * r_unit
    Gm[np.ix_(Y_PLANE, X_PLANE)] = -_T @ ip_r
    Gm[np.ix_(X_PLANE, Y_PLANE)] = ip_r @ _T
    # Circulatory (rotating internal damping) coupling, skew-symmetric.
    Kc[np.ix_(X_PLANE, Y_PLANE)] = k_b @ _T
    Kc[np.ix_(Y_PLANE, X_PLANE)] = -_T @ k_b
    return ShaftElement(M=M, G=Gm, K=K, Kc=Kc)


def rigid_disk(
    mass: float, diametral_inertia: float, polar_inertia: float, offset: float = 0.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Rigid disk matrices of eq. (2.12)-(2.13) at one node, DOFs ``[x, y, alpha, beta]``.

    Parameters
    ----------
    mass : float
        Disk mass m_d, kg.
    diametral_inertia : float
        I_d about a diameter through the node, kg m^2.
    polar_inertia : float
        I_p, kg m^2.
    offset : float
        ``l_d`` of eq. (2.12), m. With the signs of eq. (2.12) and ``beta = dx/dz`` the centre
        of mass lies at ``z_node - l_d``. The rig's bodies are centred on their nodes (0).

    Returns
    -------
    M : ndarray (4, 4)
        Mass matrix (eq. 2.12).
    G : ndarray (4, 4)
        Gyroscopic matrix (eq. 2.13), multiplied by Omega in the equation of motion.
    """
    m, ld = mass, offset
    M = np.array(
        [
            [m, 0.0, 0.0, -ld * m],
            [0.0, m, ld * m, 0.0],
            [0.0, ld * m, diametral_inertia, 0.0],
            [-ld * m, 0.0, 0.0, diametral_inertia],
        ]
    )
    G = np.zeros((4, 4))
    G[2, 3] = polar_inertia
    G[3, 2] = -polar_inertia
    return M, G
