"""
Linear rotor/AMB plant in first-order form (eq. 2.15-2.16) and its PID closed loop (eq. 2.47).

The plant state is ``x = [q, q', i]``: nodal DOFs, their rates and, when the amplifier model is
``coil``, the four coil control currents. The AMB force per axis is the linearised law
(eq. 2.37-2.40) ``f = K_i i + K_z x_b`` (``x_b`` the rotor displacement at the bearing along the
axis; the negative stiffness ``K_z`` is folded into the stiffness matrix).

Coil dynamics (eq. 2.42, ``v = R i + L di/dt``) are driven by a current-loop amplifier with
resistance feed-forward, ``v = (L w_a - R)(i_ref - i) + R i_ref``, so that
``i' = w_a (i_ref - i)`` with ``w_a`` = ``amb.amplifier_bandwidth`` (an assumption: the thesis
treats the amplifier-coil current gain as constant over the operating range, section 2.4).
Voltage saturation is not modelled.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from amb_common.rig import PidGains, Rig
from amb_plant_sim.pid import StateSpace, pid_state_space
from amb_plant_sim.rotor import RotorModel, build_rotor


@dataclass(frozen=True)
class LinearPlant:
    """
    Continuous linear plant at one running speed.

    Attributes
    ----------
    rotor : RotorModel
        The FE rotor.
    omega : float
        Running speed, rad/s.
    A : ndarray (nx, nx)
        State matrix.
    B_i : ndarray (nx, 4)
        Input: control current per axis (A) [b1x, b1y, b2x, b2y] (demand current for ``coil``).
    B_f : ndarray (nx, 2N)
        Input: external forces (N) at every node, ordered ``[fx_0, fy_0, fx_1, ...]``.
    B_a : ndarray (nx, 2)
        Input: base acceleration (m/s^2) in x, y (eq. 3.6: force ``-M y''``).
    C_in : ndarray (4, nx)
        PID inputs: inner sensor displacement per control axis, m.
    C_s : ndarray (8, nx)
        All sensors [x1, y1, ..., x4, y4], m.
    C_b : ndarray (4, nx)
        Rotor displacement at the bearings per axis, m.
    C_i : ndarray (4, nx) or None
        Coil currents (only with the coil amplifier model).
    sensor_nodes, bearing_nodes : tuple of int
        FE nodes of the four sensor planes and the two bearings.
    """

    rotor: RotorModel
    omega: float
    A: NDArray[np.float64]
    B_i: NDArray[np.float64]
    B_f: NDArray[np.float64]
    B_a: NDArray[np.float64]
    C_in: NDArray[np.float64]
    C_s: NDArray[np.float64]
    C_b: NDArray[np.float64]
    C_i: NDArray[np.float64] | None
    sensor_nodes: tuple[int, ...]
    bearing_nodes: tuple[int, ...]

    @property
    def n_states(self) -> int:
        """Number of plant states."""
        return int(self.A.shape[0])

    def position_rows(self, nodes: list[int]) -> NDArray[np.float64]:
        """Output rows (2k, nx) for ``[x, y]`` at each node in ``nodes``, m."""
        C = np.zeros((2 * len(nodes), self.n_states))
        C[:, : self.rotor.n_dof] = self.rotor.translation_matrix(nodes)
        return C

    def velocity_rows(self, nodes: list[int]) -> NDArray[np.float64]:
        """Output rows (2k, nx) for ``[x', y']`` at each node in ``nodes``, m/s."""
        n = self.rotor.n_dof
        C = np.zeros((2 * len(nodes), self.n_states))
        C[:, n : 2 * n] = self.rotor.translation_matrix(nodes)
        return C


def build_plant(
    rig: Rig,
    omega: float,
    rotor: RotorModel | None = None,
    amb_stiffness: bool = True,
    amplifier: str | None = None,
) -> LinearPlant:
    """
    Linear plant (rotor + AMB law + optional coil dynamics) at running speed ``omega`` (rad/s).

    Parameters
    ----------
    rig : Rig
        Rig description.
    omega : float
        Running speed, rad/s.
    rotor : RotorModel, optional
        A prebuilt rotor (e.g. with another element count); default from ``rig``.
    amb_stiffness : bool
        Include the negative stiffness ``K_z`` (``False`` gives the free-free rotor).
    amplifier : str, optional
        ``ideal`` or ``coil``; default ``rig.amb.amplifier``.

    Returns
    -------
    LinearPlant
    """
    rot = build_rotor(rig) if rotor is None else rotor
    amp = rig.amb.amplifier if amplifier is None else amplifier
    n = rot.n_dof
    sensor_nodes = tuple(rot.node_at(p.z) for p in rig.sensor_planes)
    bearing_nodes = tuple(rot.node_at(b.z) for b in rig.bearings)
    Tb = rot.translation_matrix(list(bearing_nodes))  # (4, n)
    K = rot.stiffness(omega)
    if amb_stiffness:
        K = K - rig.amb.Kz * Tb.T @ Tb
    Minv = np.linalg.inv(rot.M)
    D = omega * rot.G + rot.damping()
    n_coil = 4 if amp == "coil" else 0
    nx = 2 * n + n_coil
    A = np.zeros((nx, nx))
    A[:n, n : 2 * n] = np.eye(n)
    A[n : 2 * n, :n] = -Minv @ K
    A[n : 2 * n, n : 2 * n] = -Minv @ D
    force_per_current = Minv @ Tb.T * rig.amb.Ki  # (n, 4)
    B_i = np.zeros((nx, 4))
    C_i = None
    if n_coil:
        wa = rig.amb.amplifier_bandwidth
        A[n : 2 * n, 2 * n :] = force_per_current
        A[2 * n :, 2 * n :] = -wa * np.eye(4)
        B_i[2 * n :, :] = wa * np.eye(4)
        C_i = np.zeros((4, nx))
        C_i[:, 2 * n :] = np.eye(4)
    else:
        B_i[n : 2 * n, :] = force_per_current
    all_nodes = list(range(rot.n_nodes))
    B_f = np.zeros((nx, 2 * rot.n_nodes))
    B_f[n : 2 * n, :] = Minv @ rot.translation_matrix(all_nodes).T
    B_a = np.zeros((nx, 2))
    B_a[n : 2 * n, :] = -rot.rigid_modes()[:, :2]  # M^-1 (-M r) a = -r a
    Ts = rot.translation_matrix(list(sensor_nodes))
    C_s = np.zeros((8, nx))
    C_s[:, :n] = Ts
    feed = [rig.bearings[b].sensor_plane - 1 for b in range(2)]
    rows = [2 * feed[0], 2 * feed[0] + 1, 2 * feed[1], 2 * feed[1] + 1]
    C_in = C_s[rows, :].copy()
    C_b = np.zeros((4, nx))
    C_b[:, :n] = Tb
    return LinearPlant(
        rotor=rot,
        omega=float(omega),
        A=A,
        B_i=B_i,
        B_f=B_f,
        B_a=B_a,
        C_in=C_in,
        C_s=C_s,
        C_b=C_b,
        C_i=C_i,
        sensor_nodes=sensor_nodes,
        bearing_nodes=bearing_nodes,
    )


@dataclass(frozen=True)
class ClosedLoop:
    """
    Continuous rotor/AMB/PID closed loop of eq. (2.47), state ``[x, x_k]``.

    Attributes
    ----------
    plant : LinearPlant
    pid : StateSpace
        The controller (input m, output A).
    A : ndarray
        Closed-loop state matrix.
    B_i : ndarray (n, 4)
        Additional current per axis in parallel with the PID (A), e.g. wavelet control.
    B_f : ndarray (n, 2N)
        External nodal forces, N.
    B_u : ndarray (n, 4)
        Force at each bearing axis in parallel with the AMB force, N (``B_i / K_i``).
    """

    plant: LinearPlant
    pid: StateSpace
    A: NDArray[np.float64]
    B_i: NDArray[np.float64]
    B_f: NDArray[np.float64]
    B_u: NDArray[np.float64]

    @property
    def n_plant(self) -> int:
        """Number of plant states (the PID states follow)."""
        return self.plant.n_states

    def output(self, C_plant: NDArray[np.float64]) -> NDArray[np.float64]:
        """Extend plant output rows with zeros over the PID states."""
        return np.hstack([C_plant, np.zeros((C_plant.shape[0], self.pid.A.shape[0]))])


def close_loop(plant: LinearPlant, pid: StateSpace, current_gain: float) -> ClosedLoop:
    """
    Close the decentralised PID around the plant (eq. 2.47).

    Parameters
    ----------
    plant : LinearPlant
    pid : StateSpace
        Controller from inner-sensor displacement (m) to demand current (A).
    current_gain : float
        K_i, N/A (for the parallel-force input ``B_u``).

    Returns
    -------
    ClosedLoop
    """
    nx = plant.n_states
    nk = pid.A.shape[0]
    A = np.zeros((nx + nk, nx + nk))
    A[:nx, :nx] = plant.A + plant.B_i @ pid.D @ plant.C_in
    A[:nx, nx:] = plant.B_i @ pid.C
    A[nx:, :nx] = pid.B @ plant.C_in
    A[nx:, nx:] = pid.A
    B_i = np.vstack([plant.B_i, np.zeros((nk, 4))])
    B_f = np.vstack([plant.B_f, np.zeros((nk, plant.B_f.shape[1]))])
    return ClosedLoop(plant, pid, A, B_i, B_f, B_i / current_gain)


def build_closed_loop(
    rig: Rig,
    omega: float,
    rotor: RotorModel | None = None,
    gains: PidGains | None = None,
    amplifier: str | None = None,
) -> ClosedLoop:
    """
    Rig closed loop with the Table 2.3 PID (or ``gains``) at speed ``omega`` (rad/s).

    Parameters
    ----------
    rig : Rig
    omega : float
        Running speed, rad/s.
    rotor : RotorModel, optional
        Prebuilt rotor.
    gains : PidGains, optional
        Override of the PID gains (figure 2.13 varies K_p).
    amplifier : str, optional
        ``ideal`` or ``coil``.

    Returns
    -------
    ClosedLoop
    """
    plant = build_plant(rig, omega, rotor=rotor, amplifier=amplifier)
    pid = pid_state_space(rig.pid if gains is None else gains, rig.amb.Ki)
    return close_loop(plant, pid, rig.amb.Ki)
