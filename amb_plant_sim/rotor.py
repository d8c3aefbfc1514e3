"""
Assembled rotor model of eq. (2.14): mesh, M, G, K, K_c and distribution matrices.

``M q'' + (Omega G + C) q' + K q = B_f f + B_u u`` with ``q`` the nodal DOFs of eq. (2.1),
4 per node ``[x, y, alpha, beta]``. The AMB negative stiffness is NOT part of ``K`` here; it is
added by the closed loop (:mod:`amb_plant_sim.closed_loop`), so that the free-free rotor of
figures 2.4, 2.6 and 2.7 is this model alone.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from amb_common.errors import RigError
from amb_common.rig import Rig, RigidDisk, ShaftData
from amb_plant_sim.elements import rigid_disk, shaft_element

DOF_NAMES = ("x", "y", "alpha", "beta")


def mesh_nodes(stations: Sequence[float], length: float, elements: int) -> NDArray[np.float64]:
    """
    Node positions with a node at every station and ``elements`` elements in total.

    Each interval between consecutive stations gets at least one element; the remaining
    elements go one at a time to the interval whose elements are currently longest
    (this minimises the longest element). Intervals are divided uniformly.

    Parameters
    ----------
    stations : sequence of float
        Positions that must be nodes, m (the ends are added).
    length : float
        Shaft length, m.
    elements : int
        Number of elements wanted.

    Returns
    -------
    ndarray (elements + 1,)
        Node positions, m, increasing from 0 to ``length``.

    Raises
    ------
    RigError
        If ``elements`` is smaller than the number of intervals between stations.
    """
    st = np.unique(np.round(np.r_[0.0, np.asarray(stations, float), length], 9))
    seg = np.diff(st)
    if np.any(seg <= 0):
        raise RigError("stations must lie within the shaft")
    if elements < seg.size:
        raise RigError(
            f"{elements} elements cannot put a node at each of the {st.size} stations; "
            f"use at least {seg.size} elements"
        )
    n = np.ones(seg.size, dtype=int)
    for _ in range(elements - seg.size):
        n[int(np.argmax(seg / n))] += 1
    z = [st[0]]
    for a, b, k in zip(st[:-1], st[1:], n, strict=True):
        z.extend(np.linspace(a, b, k + 1)[1:])
    return np.asarray(z)


@dataclass(frozen=True)
class RotorModel:
    """
    Assembled free-free rotor (eq. 2.14) on nodes ``z``.

    Attributes
    ----------
    z : ndarray (N,)
        Node positions, m from the drive end.
    M, G, K, Kc : ndarray (4N, 4N)
        Mass (kg), gyroscopic (kg m^2, multiplied by Omega), bending stiffness (N/m) and
        circulatory matrix of eq. (2.10) (N/m).
    eta_v, eta_h : float
        Zorzi-Nelson viscous (s) and hysteretic (-) internal damping coefficients.
    """

    z: NDArray[np.float64]
    M: NDArray[np.float64]
    G: NDArray[np.float64]
    K: NDArray[np.float64]
    Kc: NDArray[np.float64]
    eta_v: float = 0.0
    eta_h: float = 0.0

    @property
    def n_nodes(self) -> int:
        """Number of nodes N."""
        return int(self.z.size)

    @property
    def n_dof(self) -> int:
        """Number of DOFs, 4N."""
        return 4 * self.n_nodes

    def node_at(self, z: float, tol: float = 1e-6) -> int:
        """Index of the node at axial position ``z`` (m); RigError if none within ``tol``."""
        i = int(np.argmin(np.abs(self.z - z)))
        if abs(self.z[i] - z) > tol:
            raise RigError(f"no FE node at z = {z} m (nearest {self.z[i]} m); add it as a station")
        return i

    @staticmethod
    def dof(node: int, name: str) -> int:
        """Global DOF index of ``name`` in ('x', 'y', 'alpha', 'beta') at ``node``."""
        return 4 * node + DOF_NAMES.index(name)

    def damping(self) -> NDArray[np.float64]:
        """Internal viscous damping matrix ``C = eta_v K_b`` (eq. 2.11), N s/m."""
        return self.eta_v * self.K

    def stiffness(self, omega: float) -> NDArray[np.float64]:
        """
        Speed-dependent stiffness of eq. (2.11), N/m.

        ``K_b / sqrt(1 + eta_h^2) + (eta_v Omega + eta_h / sqrt(1 + eta_h^2)) K_c``. The thesis
        prints the bending factor as ``(1 + zeta_h)/sqrt(1 + zeta_h)``, a typo for Zorzi &
        Nelson's ``1/sqrt(1 + eta_h^2)``, which is used here.
        """
        s = math.sqrt(1.0 + self.eta_h**2)
        return self.K / s + (self.eta_v * omega + self.eta_h / s) * self.Kc

    def translation_matrix(self, nodes: Sequence[int]) -> NDArray[np.float64]:
        """
        Output matrix picking ``[x_n, y_n]`` of each node in ``nodes`` (rows), shape (2k, 4N).

        Its transpose distributes forces ``[f_x, f_y]`` at those nodes (``B_f`` of eq. 2.14).
        """
        C = np.zeros((2 * len(nodes), self.n_dof))
        for k, n in enumerate(nodes):
            C[2 * k, 4 * n] = 1.0
            C[2 * k + 1, 4 * n + 1] = 1.0
        return C

    def rigid_modes(self) -> NDArray[np.float64]:
        """
        Rigid-body displacement fields (4N, 4): x and y translation, tilts about the origin.

        Columns: unit x translation, unit y translation, unit beta (x = z beta), unit alpha
        (y = -z alpha).
        """
        R = np.zeros((self.n_dof, 4))
        for n, zn in enumerate(self.z):
            R[4 * n, 0] = 1.0
            R[4 * n + 1, 1] = 1.0
            R[4 * n, 2] = zn
            R[4 * n + 3, 2] = 1.0
            R[4 * n + 1, 3] = -zn
            R[4 * n + 2, 3] = 1.0
        return R


def assemble(
    z: NDArray[np.float64],
    shaft: ShaftData,
    bodies: Sequence[RigidDisk] = (),
) -> RotorModel:
    """
    Assemble shaft elements between nodes ``z`` and rigid bodies at their nodes.

    Parameters
    ----------
    z : ndarray (N,)
        Node positions, m.
    shaft : ShaftData
        Shaft section, material and element options.
    bodies : sequence of RigidDisk
        Disks, cores, collars; each must sit on a node.

    Returns
    -------
    RotorModel
    """
    z = np.asarray(z, float)
    N = z.size
    n = 4 * N
    M = np.zeros((n, n))
    G = np.zeros((n, n))
    K = np.zeros((n, n))
    Kc = np.zeros((n, n))
    mat = shaft.material
    for e in range(N - 1):
        el = shaft_element(
            z[e + 1] - z[e],
            mat.E,
            mat.G,
            shaft.inertia_density,
            shaft.inner_radius,
            shaft.outer_radius,
            mat.poisson,
            shear=shaft.shear,
            rotary_inertia=shaft.rotary_inertia,
        )
        s = slice(4 * e, 4 * e + 8)
        M[s, s] += el.M
        G[s, s] += el.G
        K[s, s] += el.K
        Kc[s, s] += el.Kc
    model = RotorModel(
        z=z,
        M=M,
        G=G,
        K=K,
        Kc=Kc,
        eta_v=shaft.internal_damping_viscous,
        eta_h=shaft.internal_damping_hysteretic,
    )
    for b in bodies:
        node = model.node_at(b.z)
        Md, Gd = rigid_disk(b.mass, b.diametral_inertia, b.polar_inertia)
        s = slice(4 * node, 4 * node + 4)
        M[s, s] += Md
        G[s, s] += Gd
    return model


def build_rotor(rig: Rig, elements: int | None = None) -> RotorModel:
    """
    The rig's rotor (shaft + disks + AMB cores + collars) with ``elements`` elements.

    Parameters
    ----------
    rig : Rig
        Loaded rig description.
    elements : int, optional
        Element count (default ``rig.shaft.elements``, 14 as figure 2.7).

    Returns
    -------
    RotorModel
    """
    ne = rig.shaft.elements if elements is None else int(elements)
    z = mesh_nodes(rig.stations(), rig.shaft.length, ne)
    return assemble(z, rig.shaft, rig.rigid_bodies)
