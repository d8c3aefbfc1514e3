"""
Exact discretisation of the linear plant and the sample-lifted closed loop.

Between internal instants the plant ``x' = A x + B u`` with inputs held (zero-order hold) is
integrated exactly with the matrix exponential: ``x+ = e^{A h} x + integral_0^h e^{A s} ds B u``.
Synchronous forces ``Re(W e^{j Omega (t - t0)})`` (unbalance, eq. 3.3/5.1; rotating AMB force)
are integrated exactly too, via ``Psi = integral_0^h e^{A (h - s)} B_f e^{j Omega s} ds``, the
top-right block of ``expm([[A, B_f], [0, j Omega I]] h)``.

With no contact, linear AMB law and no saturation, the whole rotor + PID (+ amplifier) system
is linear with inputs held over one sample; the ``n_sub`` internal steps of a sample are then
lifted into one matrix pair ``s_{n+1} = F s_n + G u_n`` computed once per speed, with monitor
outputs (PID currents and journal positions at every internal step) to detect saturation and
contact, in which case the simulator recomputes that sample step by step.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from amb_plant_sim.closed_loop import LinearPlant
from amb_plant_sim.pid import StateSpace, discretize_zoh


@dataclass(frozen=True)
class StepMatrices:
    """One exact step of length ``h``: ``x+ = Phi x + Gi i + Gf f + Ga a + Re(Psi W)``."""

    h: float
    Phi: NDArray[np.float64]
    Gi: NDArray[np.float64]
    Gf: NDArray[np.float64]
    Ga: NDArray[np.float64]
    Psi: NDArray[np.complex128]


def step_matrices(plant: LinearPlant, h: float) -> StepMatrices:
    """
    Exact ZOH step matrices of the plant at step ``h`` (s), with the synchronous kernel.

    Parameters
    ----------
    plant : LinearPlant
        Continuous plant at running speed ``plant.omega``.
    h : float
        Step, s.

    Returns
    -------
    StepMatrices
    """
    A = plant.A
    nx = A.shape[0]
    B = np.hstack([plant.B_i, plant.B_f, plant.B_a])
    nb = B.shape[1]
    blk = np.zeros((nx + nb, nx + nb))
    blk[:nx, :nx] = A
    blk[:nx, nx:] = B
    E = scipy.linalg.expm(blk * h)
    Phi = E[:nx, :nx]
    n_i, n_f = plant.B_i.shape[1], plant.B_f.shape[1]
    Gi = E[:nx, nx : nx + n_i]
    Gf = E[:nx, nx + n_i : nx + n_i + n_f]
    Ga = E[:nx, nx + n_i + n_f :]
    # synchronous kernel (complex augmented exponential)
    cblk = np.zeros((nx + n_f, nx + n_f), dtype=complex)
    cblk[:nx, :nx] = A
    cblk[:nx, nx:] = plant.B_f
    cblk[nx:, nx:] = 1j * plant.omega * np.eye(n_f)
    Psi = scipy.linalg.expm(cblk * h)[:nx, nx:]
    return StepMatrices(h, Phi, Gi, Gf, Ga, Psi)


@dataclass(frozen=True)
class InputLayout:
    """Column slices of the per-sample input vector ``u`` of the lifted map."""

    i_w: slice  # parallel (wavelet) current per axis, A
    f_e: slice  # held nodal forces, N
    a_b: slice  # base acceleration, m/s^2
    o: slice  # offsets on the 4 PID input channels, m
    w_re: slice  # Re W of synchronous forces at sample start, N
    w_im: slice  # Im W
    noise: slice  # PID input noise, 4 per internal step, m
    size: int


def input_layout(n_force: int, n_sub: int) -> InputLayout:
    """Layout of ``u`` for ``n_force`` nodal force columns and ``n_sub`` internal steps."""
    sizes = [4, n_force, 2, 4, n_force, n_force, 4 * n_sub]
    edges = np.concatenate([[0], np.cumsum(sizes)])
    sl = [slice(int(a), int(b)) for a, b in itertools.pairwise(edges)]
    return InputLayout(*sl, size=int(edges[-1]))


@dataclass(frozen=True)
class SpeedDiscretisation:
    """
    Everything the simulator needs at one running speed.

    Attributes
    ----------
    omega : float
        Running speed, rad/s.
    period : float
        Sample period, s (``2 pi / (omega samples_per_rev)``).
    n_sub : int
        Internal steps per sample.
    step, substep : StepMatrices
        Exact matrices for the internal step ``h = period / n_sub`` and the contact sub-step.
    n_contact_sub : int
        Sub-steps per internal step while in contact.
    pid : StateSpace
        PID discretised (ZOH) at ``h``.
    F, G : ndarray
        Lifted sample map ``s+ = F s + G u`` on ``s = [x, x_k]``.
    Ms, Mu : ndarray
        Monitors ``m = Ms s + Mu u``: per internal step, PID currents (4) then journal
        positions at the clearance bearings (2 each), then the positions at the sample end.
    layout : InputLayout
    L : ndarray
        ``[[F, G], [Ms, Mu]]`` stacked: one product gives the next state and the monitors.
    cur_idx : ndarray (n_sub, 4) int
        Rows of the monitors holding the PID currents of each internal step.
    pos_idx : ndarray (n_sub + 1, k, 2) int
        Rows of the monitors holding the journal positions (internal steps and sample end).
    """

    omega: float
    period: float
    n_sub: int
    step: StepMatrices
    substep: StepMatrices
    n_contact_sub: int
    pid: StateSpace
    F: NDArray[np.float64] | None
    G: NDArray[np.float64] | None
    Ms: NDArray[np.float64] | None
    Mu: NDArray[np.float64] | None
    layout: InputLayout
    plant: LinearPlant
    L: NDArray[np.float64] | None
    cur_idx: NDArray[np.int64] | None
    pos_idx: NDArray[np.int64] | None


def discretise(
    plant: LinearPlant,
    pid: StateSpace,
    samples_per_rev: int,
    internal_rate_min: float,
    contact_rows: NDArray[np.float64],
    n_contact_sub: int,
    lifted: bool = True,
) -> SpeedDiscretisation:
    """
    Discretise plant and PID at the plant's speed and lift one sample.

    Parameters
    ----------
    plant : LinearPlant
        Continuous plant at running speed ``plant.omega`` (> 0).
    pid : StateSpace
        Continuous PID (input m, output A).
    samples_per_rev : int
        Samples per revolution.
    internal_rate_min : float
        Minimum internal rate, Hz; ``n_sub = ceil(rate * period)``.
    contact_rows : ndarray (2k, nx)
        Journal position rows at the clearance bearings.
    n_contact_sub : int
        Sub-steps per internal step while in contact.
    lifted : bool
        Build the lifted sample map (``False`` on speed profiles, where each speed is used
        for a few samples only and the simulator steps through the internal steps).

    Returns
    -------
    SpeedDiscretisation
    """
    omega = plant.omega
    period = 2 * math.pi / (omega * samples_per_rev)
    n_sub = max(1, math.ceil(internal_rate_min * period - 1e-9))
    h = period / n_sub
    st = step_matrices(plant, h)
    sub = step_matrices(plant, h / n_contact_sub)
    pd = discretize_zoh(pid, h)
    nx = plant.n_states
    nk = pd.A.shape[0]
    ns = nx + nk
    nf = plant.B_f.shape[1]
    lay = input_layout(nf, n_sub)
    Cin = plant.C_in
    P = np.zeros((ns, ns))
    P[:nx, :nx] = st.Phi + st.Gi @ pd.D @ Cin
    P[:nx, nx:] = st.Gi @ pd.C
    P[nx:, :nx] = pd.B @ Cin
    P[nx:, nx:] = pd.A
    # current output at an internal instant: i = [D C_in, C] s + i_w + D (o + n_j)
    if not lifted:
        return SpeedDiscretisation(
            omega=omega,
            period=period,
            n_sub=n_sub,
            step=st,
            substep=sub,
            n_contact_sub=n_contact_sub,
            pid=pd,
            F=None,
            G=None,
            Ms=None,
            Mu=None,
            layout=lay,
            plant=plant,
            L=None,
            cur_idx=None,
            pos_idx=None,
        )
    Hi = np.hstack([pd.D @ Cin, pd.C])
    Hp = np.hstack([contact_rows, np.zeros((contact_rows.shape[0], nk))])
    n_mon = 4 + Hp.shape[0]
    Ms = np.zeros((n_sub * n_mon + Hp.shape[0], ns))
    Mu = np.zeros((Ms.shape[0], lay.size))
    T = np.eye(ns)
    U = np.zeros((ns, lay.size))
    for j in range(n_sub):
        rot = np.exp(1j * omega * j * h)
        Q = np.zeros((ns, lay.size))
        Q[:nx, lay.i_w] = st.Gi
        Q[:nx, lay.f_e] = st.Gf
        Q[:nx, lay.a_b] = st.Ga
        Q[:nx, lay.o] = st.Gi @ pd.D
        Q[nx:, lay.o] = pd.B
        Q[:nx, lay.w_re] = (st.Psi * rot).real
        Q[:nx, lay.w_im] = -(st.Psi * rot).imag
        nsl = slice(lay.noise.start + 4 * j, lay.noise.start + 4 * j + 4)
        Q[:nx, nsl] = st.Gi @ pd.D
        Q[nx:, nsl] = pd.B
        r0 = j * n_mon
        Ms[r0 : r0 + 4] = Hi @ T
        Mu[r0 : r0 + 4] = Hi @ U
        Mu[r0 : r0 + 4, lay.i_w] += np.eye(4)
        Mu[r0 : r0 + 4, lay.o] += pd.D
        Mu[r0 : r0 + 4, nsl] += pd.D
        Ms[r0 + 4 : r0 + n_mon] = Hp @ T
        Mu[r0 + 4 : r0 + n_mon] = Hp @ U
        T = P @ T
        U = P @ U + Q
    Ms[n_sub * n_mon :] = Hp @ T
    Mu[n_sub * n_mon :] = Hp @ U
    return SpeedDiscretisation(
        omega=omega,
        period=period,
        n_sub=n_sub,
        step=st,
        substep=sub,
        n_contact_sub=n_contact_sub,
        pid=pd,
        F=T,
        G=U,
        Ms=Ms,
        Mu=Mu,
        layout=lay,
        plant=plant,
        L=np.vstack([np.hstack([T, U]), np.hstack([Ms, Mu])]),
        cur_idx=np.arange(n_sub)[:, None] * n_mon + np.arange(4)[None, :],
        pos_idx=np.concatenate(
            [
                (np.arange(n_sub)[:, None] * n_mon + 4 + np.arange(Hp.shape[0])[None, :]),
                (n_sub * n_mon + np.arange(Hp.shape[0]))[None, :],
            ]
        ).reshape(n_sub + 1, -1, 2),
    )
